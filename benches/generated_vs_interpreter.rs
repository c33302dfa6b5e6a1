//! Generated code vs the interpreter (instance SPN, `Evaluator`) on the same map and
//! evidence, for `log_likelihood`, `marginals` and `mpe`, on the demo floor and on the
//! largest COLD map (Saarbrücken seq2_night1, 230 places), for both model families (the
//! GraphSPN, and the tree mixture `*_trees`, whose interpreter runs the explicit
//! `instance_spn` with the evidence raised to the model's exponent); prints the speed-up ratios
//! measured in this run, and for marginals also against the interpreter's batched mode
//! (`marginals_batch`, time per query). Also the streaming state: one `observe` plus
//! `marginals` of all places (or `marginal` of one place) vs one stateless
//! `marginals` call.
//!
//! `cargo bench --bench generated_vs_interpreter`

use std::hint::black_box;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use criterion::Criterion;
use graphspn::codegen::{AnyInputs, Builder};
use graphspn::instance::Instance;
use graphspn::interpreter::{BATCH, Evaluator, Evidence};
use graphspn::spn::Spn;
use graphspn::treemix::{TreeInstance, instance_spn};

/// The explicit instance SPN of model file `model` on demo map `file` (as
/// `generated/build.rs` compiles them: 5 seeded decompositions, or the tree mixture's
/// seeded trees), its number of mixture components, and the exponent the evidence is
/// raised to (1 for a GraphSPN).
fn reference_spn(model: &str, file: &str) -> (Spn, usize, i32) {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("generated/demo");
    let builder = Builder::new(dir.join(model), dir.join(file)).seed(0);
    // A tree mixture keeps its model's number of trees, as in `generated/build.rs`.
    let builder = if model == "model.json" {
        builder.count(5)
    } else {
        builder
    };
    match builder.load_any().expect("demo inputs") {
        AnyInputs::Graphspn(i) => {
            let d = i.decompositions.len();
            (
                Instance::build(&i.model, &i.map, i.decompositions)
                    .unwrap()
                    .spn,
                d,
                1,
            )
        }
        AnyInputs::TreeMixture(i) => {
            let t = i.trees.len();
            let gamma = i.model.evidence_exponent as i32;
            let inst = TreeInstance::build(&i.model, &i.map, i.trees).unwrap();
            (instance_spn(&inst).unwrap(), t, gamma)
        }
    }
}

macro_rules! bench_map {
    ($c:expr, $m:ident, $model:expr, $file:expr, $ratios:expr) => {{
        use graphspn_generated::$m as g;
        let (spn, components, gamma) = reference_spn($model, $file);
        assert_eq!(components, g::NUM_DECOMPOSITIONS);
        let mut eval = Evaluator::new(&spn).unwrap();
        // Deterministic, informative evidence.
        let mut e: g::Evidence = [[0.0; g::NUM_CLASSES]; g::NUM_PLACES];
        for (p, row) in e.iter_mut().enumerate() {
            for (k, x) in row.iter_mut().enumerate() {
                *x = 0.05 + ((p * 7 + k * 13) % 17) as f32 / 17.0;
            }
        }
        let rows: Vec<Vec<f64>> = e
            .iter()
            .map(|r| r.iter().map(|&x| f64::from(x).powi(gamma)).collect())
            .collect();
        let ev = Evidence::from_rows(rows);
        let free = vec![None; g::NUM_PLACES];
        let mut out: g::Marginals = [[0.0; g::NUM_CLASSES]; g::NUM_PLACES];
        let mut labels: g::Labels = [0; g::NUM_PLACES];
        let name = stringify!($m);
        let mut group = $c.benchmark_group(name);
        group.bench_function("generated/log_likelihood", |b| {
            b.iter(|| g::log_likelihood(black_box(&e)))
        });
        group.bench_function("interpreter/log_likelihood", |b| {
            b.iter(|| eval.log_likelihood(&free, black_box(&ev)))
        });
        group.bench_function("generated/marginals", |b| {
            b.iter(|| g::marginals(black_box(&e), &mut out))
        });
        group.bench_function("interpreter/marginals", |b| {
            b.iter(|| eval.marginals(&free, black_box(&ev)))
        });
        let fixed8: [&[Option<u32>]; BATCH] = [&free; BATCH];
        let ev8: [&Evidence; BATCH] = [&ev; BATCH];
        group.bench_function("interpreter/marginals_batch8", |b| {
            b.iter(|| eval.marginals_batch(fixed8, black_box(ev8)))
        });
        group.bench_function("generated/mpe", |b| {
            b.iter(|| g::mpe(black_box(&e), &mut labels))
        });
        group.bench_function("interpreter/mpe", |b| {
            b.iter(|| eval.mpe(&free, black_box(&ev)))
        });
        let mut state = g::State::new();
        state.set_all(&e).unwrap();
        let mut step = 0usize;
        group.bench_function("state/observe+marginals", |b| {
            b.iter(|| {
                step = (step + 1) % g::NUM_PLACES;
                let _ = state.observe(step, black_box(&e[(step * 7) % g::NUM_PLACES]));
                state.marginals(&mut out)
            })
        });
        group.finish();
        // Ratios from one timing pass each, same process.
        let time = |f: &mut dyn FnMut()| {
            let start = Instant::now();
            let mut n = 0u32;
            while start.elapsed() < Duration::from_millis(300) {
                f();
                n += 1;
            }
            start.elapsed().as_secs_f64() / f64::from(n)
        };
        let gl = time(&mut || {
            black_box(g::log_likelihood(black_box(&e)).ok());
        });
        let il = time(&mut || {
            black_box(eval.log_likelihood(&free, &ev).ok());
        });
        let gm = time(&mut || {
            black_box(g::marginals(black_box(&e), &mut out).ok());
        });
        let im = time(&mut || {
            black_box(eval.marginals(&free, &ev).ok());
        });
        // The interpreter's batched mode, per query.
        let im8 = time(&mut || {
            let _ = black_box(eval.marginals_batch(fixed8, ev8));
        }) / BATCH as f64;
        let gp = time(&mut || {
            black_box(g::mpe(black_box(&e), &mut labels).ok());
        });
        let ip = time(&mut || {
            black_box(eval.mpe(&free, &ev).ok());
        });
        let mut one = [0.0f32; g::NUM_CLASSES];
        let so = time(&mut || {
            step = (step + 1) % g::NUM_PLACES;
            let _ = state.observe(step, black_box(&e[(step * 7) % g::NUM_PLACES]));
            black_box(state.marginals(&mut out).ok());
        });
        let s1 = time(&mut || {
            step = (step + 1) % g::NUM_PLACES;
            let _ = state.observe(step, black_box(&e[(step * 7) % g::NUM_PLACES]));
            black_box(state.marginal(step, &mut one).ok());
        });
        $ratios.push(format!(
            "{name} streaming state ({} bytes): observe + marginals {:.2} µs ({:.1}x faster than stateless marginals), observe + marginal(place) {:.2} µs ({:.1}x)",
            g::STATE_BYTES,
            so * 1e6,
            gm / so,
            s1 * 1e6,
            gm / s1
        ));
        $ratios.push(format!(
            "{name} ({} places, {} instance edges): log_likelihood {:.1} µs vs {:.1} µs ({:.1}x), marginals {:.1} µs vs {:.1} µs ({:.1}x), mpe {:.1} µs vs {:.1} µs ({:.1}x); interpreter marginals batched by {BATCH}: {:.1} µs per query ({:.1}x)",
            g::NUM_PLACES,
            eval.num_edges(),
            gl * 1e6,
            il * 1e6,
            il / gl,
            gm * 1e6,
            im * 1e6,
            im / gm,
            gp * 1e6,
            ip * 1e6,
            ip / gp,
            im8 * 1e6,
            im8 / gm
        ));
    }};
}

fn main() {
    let mut c = Criterion::default().configure_from_args();
    let mut ratios: Vec<String> = Vec::new();
    let (graphspn, trees) = ("model.json", "tree_model.json");
    let (floor, saarbrucken) = ("floor.json", "saarbrucken_seq2_night1.json");
    bench_map!(c, demo_floor, graphspn, floor, ratios);
    bench_map!(c, saarbrucken_seq2_night1, graphspn, saarbrucken, ratios);
    bench_map!(c, demo_floor_trees, trees, floor, ratios);
    bench_map!(c, saarbrucken_seq2_night1_trees, trees, saarbrucken, ratios);
    c.final_summary();
    println!("generated vs interpreter (time per call, interpreter / generated):");
    for r in &ratios {
        println!("  {r}");
    }
}
