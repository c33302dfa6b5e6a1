//! Generated calls never touch the heap: a counting global allocator sees zero
//! allocations across thousands of checked and unchecked queries and streaming-state
//! updates on the demo map's modules of both model families (GraphSPN, tree mixture).
//! Only the calling thread's allocations are counted (generated code spawns no
//! thread): the test harness's own thread allocates while a test starts, and under
//! load that raced with the count.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicUsize, Ordering};

struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

thread_local! {
    /// Whether this thread's allocations are counted.
    static COUNTED: Cell<bool> = const { Cell::new(false) };
}

/// Counts one allocation if the current thread is counted.
fn count() {
    if COUNTED.try_with(Cell::get).unwrap_or(false) {
        ALLOCATIONS.fetch_add(1, Ordering::SeqCst);
    }
}

// SAFETY: forwards every call to the system allocator unchanged; only counts them.
#[allow(unsafe_code)]
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        // SAFETY: same contract as the caller's.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// Thousands of checked and unchecked queries and state updates on module `$m`;
/// returns a checksum.
macro_rules! exercise {
    ($m:ident) => {{
        use graphspn_generated::$m::{
            self as m, Evidence, Labels, Marginals, NUM_CLASSES, NUM_PLACES,
        };
        let mut e: Evidence = [[0.5; NUM_CLASSES]; NUM_PLACES];
        let mut out: Marginals = [[0.0; NUM_CLASSES]; NUM_PLACES];
        let mut labels: Labels = [0; NUM_PLACES];
        let mut one = [0.0f32; NUM_CLASSES];
        let mut s = m::State::new();
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        let mut sum = 0.0f64;
        for i in 0..1_000usize {
            // xorshift evidence, with an invalid row every 7th call to exercise the error path.
            for row in e.iter_mut() {
                for x in row.iter_mut() {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    *x = (state >> 40) as f32 / (1u64 << 24) as f32 + 1e-6;
                }
            }
            if i % 7 == 0 {
                e[i % NUM_PLACES][0] = f32::NAN;
            }
            sum += m::log_likelihood(&e).map_or(0.0, f64::from);
            sum += m::marginals(&e, &mut out).map_or(0.0, f64::from);
            sum += m::mpe(&e, &mut labels).map_or(0.0, f64::from);
            sum += m::labelled_log_likelihood(&labels, &e).map_or(0.0, f64::from);
            sum += m::marginals_unchecked(&e, &mut out).map_or(0.0, f64::from);
            let p = i % NUM_PLACES;
            let _ = s.observe(p, &e[p]);
            let _ = s.set_evidence((p * 7) % NUM_PLACES, &e[p]);
            if i % 50 == 0 {
                let _ = s.set_all(&e);
                let _ = s.clear_evidence(p);
            }
            sum += s.marginals(&mut out).map_or(0.0, f64::from);
            sum += s.marginal(p, &mut one).map_or(0.0, |()| f64::from(one[0]));
            sum += s.log_likelihood().map_or(0.0, f64::from);
        }
        sum
    }};
}

#[test]
fn generated_calls_do_not_allocate() {
    // The counter counts: a deliberate allocation on this thread is seen.
    COUNTED.with(|c| c.set(true));
    let probe = ALLOCATIONS.load(Ordering::SeqCst);
    drop(std::hint::black_box(vec![0u8; 16]));
    assert_eq!(ALLOCATIONS.load(Ordering::SeqCst) - probe, 1);
    let before = ALLOCATIONS.load(Ordering::SeqCst);
    let sum = exercise!(demo_floor) + exercise!(demo_floor_trees);
    let after = ALLOCATIONS.load(Ordering::SeqCst);
    COUNTED.with(|c| c.set(false));
    assert!(sum.is_finite());
    assert_eq!(after - before, 0, "generated calls allocated");
}
