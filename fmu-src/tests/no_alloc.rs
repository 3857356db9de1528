//! doStep must not touch the heap (real-time use): count allocations around Model::do_step,
//! including the steps where the driver hits and leaves its rail, propagators are built,
//! and the first steps after tunable parameters changed (their rebuild happens at the set).
//!
//! The counter is per thread: the test harness runs tests (and its own bookkeeping) on
//! other threads, whose allocations must not count against the stepping thread.

use ehsv_actuator::model::Model;
use ehsv_actuator::variables::vr;
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

struct Counting;

thread_local! {
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // `try_with`: a thread being torn down has no counter left; it is not stepping.
        let _ = ALLOCATIONS.try_with(|n| n.set(n.get() + 1));
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn allocations() -> usize {
    ALLOCATIONS.with(|n| n.get())
}

/// Allocations made by this thread while `f` runs.
fn allocations_in(f: impl FnOnce()) -> usize {
    let before = allocations();
    f();
    allocations() - before
}

#[test]
fn the_counter_counts_this_thread_only() {
    assert_eq!(allocations_in(|| drop(std::hint::black_box(vec![1u8; 16]))), 1);
    let other = allocations_in(|| {
        std::thread::spawn(|| {
            for k in 0..1000 {
                drop(std::hint::black_box(vec![0u8; 16 + k]));
            }
        })
        .join()
        .unwrap()
    });
    // Spawning allocates here (thread handle, name); the other thread's 1000 do not.
    assert!(other < 100, "{other} allocations counted for spawning one thread");
}

#[test]
fn do_step_does_not_allocate() {
    // Each driver through each solver.method (0 exact, 1 fixed_cost).
    for (driver, method) in [0.0, 1.0, 2.0, 3.0, 4.0].into_iter().flat_map(|d| [(d, 0.0), (d, 1.0)])
    {
        let mut m = Model::new();
        m.set(vr::DRIVER, driver).unwrap();
        m.set(vr::SOLVER_METHOD, method).unwrap();
        m.initialize().unwrap();
        for (k, i_ref) in [5e-3, -10e-3, 0.0].into_iter().enumerate() {
            m.set(vr::I_REF, i_ref).unwrap();
            let n = allocations_in(|| {
                for _ in 0..30 {
                    m.do_step(m.time(), 1e-4 * (1 + k) as f64 / 3.0).unwrap();
                }
            });
            assert_eq!(n, 0, "driver {driver}, method {method}, i_ref {i_ref}: doStep allocated");
        }
    }
}

#[test]
fn steps_after_a_tunable_change_do_not_allocate() {
    let cases = [(2.0, vr::DRIVER_KP), (3.0, vr::INDUSTRIAL_KP), (4.0, vr::HBRIDGE_KP)];
    for ((driver, gain), method) in cases.into_iter().flat_map(|c| [(c, 0.0), (c, 1.0)]) {
        let mut m = Model::new();
        m.set(vr::DRIVER, driver).unwrap();
        m.set(vr::SOLVER_METHOD, method).unwrap();
        m.initialize().unwrap();
        m.set(vr::I_REF, 5e-3).unwrap();
        for scale in [0.5, 2.0] {
            let value = m.get(gain).unwrap() * scale;
            m.set(gain, value).unwrap();
            m.set(vr::CYLINDER_MASS, 5.0 * scale).unwrap();
            let n = allocations_in(|| {
                for _ in 0..30 {
                    m.do_step(m.time(), 1e-4).unwrap();
                }
            });
            assert_eq!(
                n, 0,
                "driver {driver}, method {method}: doStep after a tunable change allocated"
            );
        }
    }
}
