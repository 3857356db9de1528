//! Clocks and per-call statistics. Thread CPU time (CLOCK_THREAD_CPUTIME_ID) counts only
//! the work of the calling thread, so time lost to preemption on a busy machine shows in
//! wall time but not there.

use std::hint::black_box;
use std::sync::OnceLock;
use std::time::Instant;

/// CPU time consumed by the calling thread (s).
pub fn thread_cpu() -> f64 {
    let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: valid clock id and a writable timespec.
    let rc = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    assert_eq!(rc, 0, "clock_gettime(CLOCK_THREAD_CPUTIME_ID) failed");
    ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
}

/// Durations of single calls (s) in call order, collected into a buffer allocated up front.
#[derive(Clone)]
pub struct Samples {
    values: Vec<f64>,
}

/// Mean, 99.9th percentile and maximum of the samples (s), and which call took the maximum.
#[derive(Clone, Copy, Debug, Default)]
pub struct Summary {
    pub mean: f64,
    pub p999: f64,
    pub max: f64,
    pub slowest: usize,
}

impl Samples {
    pub fn with_capacity(n: usize) -> Samples {
        Samples { values: Vec::with_capacity(n) }
    }

    #[inline]
    pub fn push(&mut self, seconds: f64) {
        self.values.push(seconds);
    }

    /// Keeps, call by call, the shorter of this run's time and `other`'s (another run of the
    /// same calls): what each call costs without the interrupts and hypervisor stalls that a
    /// busy machine charges to whichever call is running.
    pub fn keep_shorter(&mut self, other: &Samples) {
        for (mine, theirs) in self.values.iter_mut().zip(&other.values) {
            *mine = mine.min(*theirs);
        }
    }

    /// The longest sample (0 if none).
    pub fn longest(&self) -> f64 {
        self.values.iter().copied().fold(0.0, f64::max)
    }

    /// The sums of each `legs` consecutive calls: with the calls of a lock-step run (step
    /// after step, leg after leg), the time of each step's doSteps of all instances together.
    pub fn lock_steps(&self, legs: usize) -> Samples {
        Samples { values: self.values.chunks(legs.max(1)).map(|c| c.iter().sum()).collect() }
    }

    /// The slowest call from call `first` on: its index and time.
    pub fn slowest_from(&self, first: usize) -> Option<(usize, f64)> {
        (first..self.values.len())
            .max_by(|&a, &b| self.values[a].total_cmp(&self.values[b]))
            .map(|k| (k, self.values[k]))
    }

    pub fn summary(&self) -> Summary {
        if self.values.is_empty() {
            return Summary::default();
        }
        let n = self.values.len();
        let mean = self.values.iter().sum::<f64>() / n as f64;
        let slowest = self.slowest_from(0).map_or(0, |(k, _)| k);
        let mut sorted = self.values.clone();
        sorted.sort_by(f64::total_cmp);
        let rank = ((0.999 * n as f64).ceil() as usize).clamp(1, n) - 1;
        Summary { mean, p999: sorted[rank], max: sorted[n - 1], slowest }
    }
}

/// The times of the same calls over several timed runs. Every workload is deterministic: call
/// k does the same work in every run, so its shortest time over the runs is that work. What a
/// run adds on top (interrupts, hypervisor stalls and preemption, which the clock charges to
/// whichever thread is running) belongs to the machine, not to the FMU, and shows only in the
/// longest sample of all.
pub struct Repeats {
    /// Call by call, the shortest time over the runs: the work of each call.
    pub shortest: Samples,
    /// The longest single sample of any run: the slowest call as the machine ran it.
    pub longest: f64,
}

impl Repeats {
    pub fn new(first_run: Samples) -> Repeats {
        Repeats { longest: first_run.longest(), shortest: first_run }
    }

    /// Takes in another run of the same calls.
    pub fn add(&mut self, run: &Samples) {
        self.longest = self.longest.max(run.longest());
        self.shortest.keep_shorter(run);
    }
}

/// Wall and thread-CPU time of one call.
pub struct Stopwatch {
    wall: Instant,
    cpu: f64,
}

impl Stopwatch {
    #[inline]
    pub fn start() -> Stopwatch {
        Stopwatch { wall: Instant::now(), cpu: thread_cpu() }
    }

    /// (wall, cpu) seconds since start, the clocks' own cost included (see [`clock_cost`]).
    #[inline]
    pub fn read(&self) -> (f64, f64) {
        let cpu = thread_cpu() - self.cpu;
        (self.wall.elapsed().as_secs_f64(), cpu)
    }
}

/// Empty measurements taken to find what the clocks themselves cost.
const CLOCK_PROBES: usize = 20_000;

/// What a [`Stopwatch`] adds to every call it times, (wall, cpu) seconds: the shortest of
/// [`CLOCK_PROBES`] measurements of nothing. A thread-CPU clock read is a system call (the
/// vDSO serves only the wall clocks), several tenths of a microsecond on a virtual machine:
/// more than an idle doStep's whole work, so it is taken off every timed call.
pub fn clock_cost() -> (f64, f64) {
    static COST: OnceLock<(f64, f64)> = OnceLock::new();
    *COST.get_or_init(|| {
        (0..CLOCK_PROBES).fold((f64::INFINITY, f64::INFINITY), |(wall, cpu), _| {
            let watch = Stopwatch::start();
            black_box(());
            let (w, c) = watch.read();
            (wall.min(w), cpu.min(c))
        })
    })
}
