//! doStep must not touch the heap (real-time use): count allocations around Model::do_step,
//! including the steps where the driver hits and leaves its rail and propagators are built.

use ehsv_actuator::model::Model;
use ehsv_actuator::variables::vr;
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

struct Counting;
static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::SeqCst);
        System.alloc(layout)
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        System.dealloc(ptr, layout)
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn do_step_does_not_allocate() {
    for driver in [0.0, 1.0, 2.0, 3.0, 4.0] {
        let mut m = Model::new();
        m.set(vr::DRIVER, driver).unwrap();
        m.initialize().unwrap();
        let before = ALLOCATIONS.load(Ordering::SeqCst);
        for (k, i_ref) in [5e-3, -10e-3, 0.0].into_iter().enumerate() {
            m.set(vr::I_REF, i_ref).unwrap();
            for _ in 0..30 {
                m.do_step(m.time(), 1e-4 * (1 + k) as f64 / 3.0).unwrap();
            }
        }
        let after = ALLOCATIONS.load(Ordering::SeqCst);
        assert_eq!(after - before, 0, "driver {driver}: doStep allocated");
    }
}
