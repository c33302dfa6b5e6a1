//! A control-loop-style program that uses only compiled maps
//! (`graphspn_generated::demo_floor`, the GraphSPN, and `demo_floor_trees`, the tree
//! mixture of the same office floor: the same API): a robot explores the demo floor
//! breadth-first from place 0, gets noisy evidence about each place it reaches, and
//! after every step fuses it into each model's streaming `State` (`observe`: only the
//! parts of the model containing that place are re-evaluated), reads the marginals of
//! all places from it and prints, per model, the accuracy of the best labelling against
//! the ground truth (all annotated places, and those visited so far), and the per-step
//! latency (median and p99 over repeated updates) next to what a full stateless
//! recomputation costs. Both models see the same evidence sequence.
//!
//! Everything lives in fixed-size arrays; a counting global allocator asserts that
//! the control loop performs zero heap allocations.
//!
//! Run: `cargo run --release --example firmware [-- --model graphspn|trees|both]`
//! (default `both`; `GRAPHSPN_EXAMPLE_MODEL` works too).

use std::alloc::{GlobalAlloc, Layout, System};
use std::io::Write;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use graphspn_generated::demo_floor::{
    self, CLASS_NAMES, Evidence, Marginals, NUM_CLASSES, NUM_PLACES, PLACE_IDS,
};
use graphspn_generated::demo_floor_trees;
use graphspn_generated::demo_floor_truth::{EDGES, TRUTH};

struct Counting;
static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards every call to the system allocator unchanged; only counts them.
#[allow(unsafe_code)]
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: same contract as the caller's.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// Timed repetitions of the per-step update per step.
const REPS: usize = 51;
/// Timed repetitions of the full recomputation per step (for comparison).
const FULL_REPS: usize = 11;
/// Probability that the place-recognition "sensor" favours the true class.
const SENSOR_ACCURACY: f32 = 0.7;

/// A tiny seeded PRNG (SplitMix64): no allocation, reproducible.
struct SplitMix(u64);

impl SplitMix {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    fn unit(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u64 << 24) as f32
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

/// Breadth-first order of the places from place 0 (unreached places appended).
fn bfs_order() -> [usize; NUM_PLACES] {
    let mut order = [0usize; NUM_PLACES];
    let mut seen = [false; NUM_PLACES];
    let (mut head, mut tail) = (0, 0);
    for start in 0..NUM_PLACES {
        if seen[start] {
            continue;
        }
        seen[start] = true;
        order[tail] = start;
        tail += 1;
        while head < tail {
            let p = order[head];
            head += 1;
            for &(a, b) in EDGES.iter() {
                let q = if usize::from(a) == p {
                    usize::from(b)
                } else if usize::from(b) == p {
                    usize::from(a)
                } else {
                    continue;
                };
                if !seen[q] {
                    seen[q] = true;
                    order[tail] = q;
                    tail += 1;
                }
            }
        }
    }
    order
}

/// Noisy evidence about a place of class `truth`: the sensor favours the true class
/// with probability [`SENSOR_ACCURACY`], otherwise a random wrong one.
fn sense(rng: &mut SplitMix, truth: u16) -> [f32; NUM_CLASSES] {
    let mut row = [0.0f32; NUM_CLASSES];
    for x in row.iter_mut() {
        *x = 0.05 + 0.1 * rng.unit();
    }
    if truth == demo_floor::UNKNOWN {
        return [1.0; NUM_CLASSES];
    }
    let favoured = if rng.unit() < SENSOR_ACCURACY {
        usize::from(truth)
    } else {
        (usize::from(truth) + 1 + rng.below(NUM_CLASSES - 1)) % NUM_CLASSES
    };
    row[favoured] = 0.6 + 0.4 * rng.unit();
    row
}

fn argmax(row: &[f32; NUM_CLASSES]) -> usize {
    let mut best = 0;
    for (k, &v) in row.iter().enumerate() {
        if v > row[best] {
            best = k;
        }
    }
    best
}

/// One model's side of the loop: its streaming state, marginals and latencies.
struct Run<S> {
    name: &'static str,
    state: S,
    marginals: Marginals,
    full: Marginals,
    lat: [u32; REPS],
    full_lat: [u32; FULL_REPS],
    step_p50: [u32; NUM_PLACES],
    full_p50: [u32; NUM_PLACES],
}

impl<S> Run<S> {
    fn new(name: &'static str, state: S) -> Self {
        Run {
            name,
            state,
            marginals: [[0.0; NUM_CLASSES]; NUM_PLACES],
            full: [[0.0; NUM_CLASSES]; NUM_PLACES],
            lat: [0; REPS],
            full_lat: [0; FULL_REPS],
            step_p50: [0; NUM_PLACES],
            full_p50: [0; NUM_PLACES],
        }
    }

    /// Accuracy (%) of the best labelling over all annotated places and over the
    /// annotated places visited in `visited`.
    fn accuracy(&self, visited: &[usize]) -> (f64, f64) {
        let (mut right, mut right_visited, mut labelled, mut labelled_visited) =
            (0u32, 0u32, 0u32, 0u32);
        for (p, row) in self.marginals.iter().enumerate() {
            if TRUTH[p] == demo_floor::UNKNOWN {
                continue;
            }
            let ok = argmax(row) == usize::from(TRUTH[p]);
            labelled += 1;
            right += u32::from(ok);
            if visited.contains(&p) {
                labelled_visited += 1;
                right_visited += u32::from(ok);
            }
        }
        (
            100.0 * f64::from(right) / f64::from(labelled.max(1)),
            100.0 * f64::from(right_visited) / f64::from(labelled_visited.max(1)),
        )
    }
}

/// The closing line of one model: final accuracy, median step and full latency.
fn summary<S>(r: &mut Run<S>, state_bytes: usize, order: &[usize]) -> String {
    r.step_p50.sort_unstable();
    r.full_p50.sort_unstable();
    let (s, f) = (
        f64::from(r.step_p50[NUM_PLACES / 2]) / 1e3,
        f64::from(r.full_p50[NUM_PLACES / 2]) / 1e3,
    );
    let (all, _) = r.accuracy(order);
    format!(
        "{}: final accuracy {all:.1}%, median step (observe + marginals) {s:.1} µs vs {f:.1} µs for a full recomputation ({:.1}x), state {state_bytes} bytes",
        r.name,
        f / s.max(1e-3)
    )
}

/// One step of module `$m` on run `$r`: fuse the observation, read all marginals from
/// the state, time the same update (re-setting the fused row) `REPS` times and a full
/// stateless recomputation `FULL_REPS` times. Returns `(ln S, p50 ns, p99 ns)`.
macro_rules! step {
    ($m:ident, $r:expr, $step:expr, $place:expr, $row:expr) => {{
        let r = &mut $r;
        let mut ll = match r
            .state
            .observe($place, $row)
            .and_then(|()| r.state.marginals(&mut r.marginals))
        {
            Ok(v) => v,
            Err(e) => panic!("{}: step {}: inference failed: {e}", r.name, $step),
        };
        for l in r.lat.iter_mut() {
            let t = Instant::now();
            let fused = r.state.evidence()[$place];
            ll = match r
                .state
                .set_evidence($place, &fused)
                .and_then(|()| r.state.marginals(&mut r.marginals))
            {
                Ok(v) => v,
                Err(e) => panic!("{}: step {}: inference failed: {e}", r.name, $step),
            };
            *l = t.elapsed().as_nanos() as u32;
        }
        let evidence: Evidence = *r.state.evidence();
        for l in r.full_lat.iter_mut() {
            let t = Instant::now();
            let _ = $m::marginals(&evidence, &mut r.full);
            *l = t.elapsed().as_nanos() as u32;
        }
        r.full_lat.sort_unstable();
        r.lat.sort_unstable();
        r.step_p50[$step] = r.lat[REPS / 2];
        r.full_p50[$step] = r.full_lat[FULL_REPS / 2];
        (ll, r.lat[REPS / 2], r.lat[REPS * 99 / 100])
    }};
}

/// Which models the example runs.
fn models() -> (bool, bool) {
    let arg = std::env::args()
        .skip_while(|a| a != "--model")
        .nth(1)
        .or_else(|| std::env::var("GRAPHSPN_EXAMPLE_MODEL").ok())
        .unwrap_or_else(|| "both".into());
    match arg.as_str() {
        "graphspn" => (true, false),
        "trees" | "tree_mixture" | "tree-mixture" => (false, true),
        "both" => (true, true),
        other => {
            eprintln!("--model {other}: expected graphspn, trees or both");
            std::process::exit(2);
        }
    }
}

fn main() {
    let (use_spn, use_trees) = models();
    let order = bfs_order();
    let labelled = TRUTH.iter().filter(|&&t| t != demo_floor::UNKNOWN).count();
    let mut out = std::io::stdout().lock();
    let _ = writeln!(
        out,
        "demo floor: {NUM_PLACES} places ({labelled} annotated), {NUM_CLASSES} classes; GraphSPN: {} decompositions, tree mixture: {} trees; exploring breadth-first from place {}",
        demo_floor::NUM_DECOMPOSITIONS,
        demo_floor_trees::NUM_TREES,
        PLACE_IDS[0]
    );
    let _ = writeln!(
        out,
        "per step and model: accuracy of the best labelling (all annotated places / visited ones), latency of one observe + marginals (median, p99) and of a full stateless marginals"
    );
    let _ = out.flush();
    let mut rng = SplitMix(2018);
    let mut spn = Run::new("GraphSPN", demo_floor::State::new());
    let mut trees = Run::new("tree mixture", demo_floor_trees::State::new());
    let before = ALLOCATIONS.load(Ordering::Relaxed);
    for (step, &place) in order.iter().enumerate() {
        let truth = TRUTH[place];
        let row = sense(&mut rng, truth);
        let seen = argmax(&row);
        let visited = &order[..=step];
        let _ = write!(
            out,
            "step {:>2} place {:>3} ({:>3} seen as {:>3})",
            step,
            PLACE_IDS[place],
            if truth == demo_floor::UNKNOWN {
                "?"
            } else {
                CLASS_NAMES[usize::from(truth)]
            },
            CLASS_NAMES[seen],
        );
        if use_spn {
            let (ll, p50, p99) = step!(demo_floor, spn, step, place, &row);
            let (all, vis) = spn.accuracy(visited);
            let _ = write!(
                out,
                " | GraphSPN {all:>5.1}% {vis:>5.1}% ln S {ll:>7.1} {:>5.1}/{:>5.1} µs (full {:>5.1})",
                f64::from(p50) / 1e3,
                f64::from(p99) / 1e3,
                f64::from(spn.full_p50[step]) / 1e3
            );
        }
        if use_trees {
            let (ll, p50, p99) = step!(demo_floor_trees, trees, step, place, &row);
            let (all, vis) = trees.accuracy(visited);
            let _ = write!(
                out,
                " | trees {all:>5.1}% {vis:>5.1}% ln S {ll:>7.1} {:>5.1}/{:>5.1} µs (full {:>5.1})",
                f64::from(p50) / 1e3,
                f64::from(p99) / 1e3,
                f64::from(trees.full_p50[step]) / 1e3
            );
        }
        let _ = writeln!(out);
    }
    let allocations = ALLOCATIONS.load(Ordering::Relaxed) - before;
    if use_spn {
        let _ = writeln!(
            out,
            "{}",
            summary(&mut spn, demo_floor::STATE_BYTES, &order)
        );
    }
    if use_trees {
        let _ = writeln!(
            out,
            "{}",
            summary(&mut trees, demo_floor_trees::STATE_BYTES, &order)
        );
    }
    let _ = writeln!(out, "heap allocations in the control loop: {allocations}");
    assert_eq!(allocations, 0, "the control loop allocated");
}
