//! Clocks and per-call statistics. Thread CPU time (CLOCK_THREAD_CPUTIME_ID) counts only
//! the work of the calling thread, so time lost to preemption on a busy machine shows in
//! wall time but not there.

use std::time::Instant;

/// CPU time consumed by the calling thread (s).
pub fn thread_cpu() -> f64 {
    let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: valid clock id and a writable timespec.
    let rc = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    assert_eq!(rc, 0, "clock_gettime(CLOCK_THREAD_CPUTIME_ID) failed");
    ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
}

/// Durations of single calls (s), collected into a buffer allocated up front.
pub struct Samples {
    values: Vec<f64>,
}

/// Mean, 99.9th percentile and maximum of the samples (s).
#[derive(Clone, Copy, Debug, Default)]
pub struct Summary {
    pub mean: f64,
    pub p999: f64,
    pub max: f64,
}

impl Samples {
    pub fn with_capacity(n: usize) -> Samples {
        Samples { values: Vec::with_capacity(n) }
    }

    #[inline]
    pub fn push(&mut self, seconds: f64) {
        self.values.push(seconds);
    }

    pub fn summary(&mut self) -> Summary {
        if self.values.is_empty() {
            return Summary::default();
        }
        let n = self.values.len();
        let mean = self.values.iter().sum::<f64>() / n as f64;
        self.values.sort_by(f64::total_cmp);
        let rank = ((0.999 * n as f64).ceil() as usize).clamp(1, n) - 1;
        Summary { mean, p999: self.values[rank], max: self.values[n - 1] }
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

    /// (wall, cpu) seconds since start.
    #[inline]
    pub fn read(&self) -> (f64, f64) {
        let cpu = thread_cpu() - self.cpu;
        (self.wall.elapsed().as_secs_f64(), cpu)
    }
}
