//! Structure fuzzing: random models (random templates via `Template::custom`, random
//! class counts, random layered or dense template SPNs with exact-zero and skewed
//! weights, one- and two-pass marginals) on random connected maps, compiled into one temporary crate, built, run
//! and compared with the interpreter. Seeds are printed with every failure.
//!
//! Scale up: `GRAPHSPN_FUZZ_STRUCTURES=5000` (built in batches of [`BATCH`] modules per
//! crate), `GRAPHSPN_FUZZ_VECTORS=N` evidence vectors per structure.

mod common;

use common::{Case, Variant, differential, env_usize};
use graphspn::codegen::{Precision, Vectorisation};
use graphspn::decompose::synthetic::random_connected_map;
use graphspn::decompose::{DecompositionParams, decompose_best};
use graphspn::learn::{DenseParams, Model, dense_structure, uniform_spn};
use graphspn::map::ClassSet;
use graphspn::spn::random::layered_spn;
use graphspn::spn::{Node, Spn};
use graphspn::template::Template;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Random structures per CI run.
const STRUCTURES: usize = 24;
/// Evidence vectors per structure.
const VECTORS: usize = 300;
/// Modules per temporary crate.
const BATCH: usize = 200;

/// A random connected template of `k` nodes: a random tree plus maybe one extra edge.
fn random_template(rng: &mut ChaCha8Rng, name: String, k: usize) -> Template {
    let mut edges: Vec<(usize, usize)> = (1..k).map(|i| (rng.random_range(0..i), i)).collect();
    if k >= 3 && rng.random_bool(0.3) {
        let (a, b) = (rng.random_range(0..k), rng.random_range(0..k));
        if a != b && !edges.iter().any(|&(x, y)| (x, y) == (a.min(b), a.max(b))) {
            edges.push((a.min(b), a.max(b)));
        }
    }
    Template::custom(name, k, &edges).expect("a connected template")
}

/// A random template SPN: half the time a layered SPN (per-node code), half the
/// time a dense region structure with random sizes (block kernels in SIMD lane
/// groups); either way with some sum weights set to exactly 0 (one positive kept;
/// weights renormalised, as the interpreter requires), sometimes very skewed.
fn random_template_spn(rng: &mut ChaCha8Rng, vars: usize, classes: u32) -> Spn {
    let mut spn = if rng.random_bool(0.5) {
        layered_spn(rng.random(), vars, classes, rng.random_range(1..=3))
    } else if vars == 1 {
        uniform_spn(1, classes).expect("a one-variable SPN")
    } else {
        let params = DenseParams {
            decompositions: rng.random_range(1..=2),
            subsets: rng.random_range(2..=3),
            sums: rng.random_range(1..=4),
            balanced: rng.random_bool(0.5),
            ..DenseParams::default()
        };
        dense_structure(vars, classes, &params, rng.random()).expect("a dense structure")
    };
    for node in spn.nodes.iter_mut() {
        if let Node::Sum { weights, .. } = node {
            weights
                .iter_mut()
                .for_each(|w| *w = rng.random_range(0.05..1.0));
        }
    }
    let zero_p = if rng.random_bool(0.5) { 0.25 } else { 0.0 };
    let skew = rng.random_bool(0.3);
    for node in spn.nodes.iter_mut() {
        if let Node::Sum { weights, .. } = node {
            let keep = rng.random_range(0..weights.len());
            for (i, w) in weights.iter_mut().enumerate() {
                if i != keep && rng.random_bool(zero_p) {
                    *w = 0.0;
                }
            }
            if skew {
                weights[keep] *= 1e6;
            }
            let total: f64 = weights.iter().sum();
            weights.iter_mut().for_each(|w| *w /= total);
        }
    }
    spn
}

fn random_case(seed: u64, vectors: usize) -> Case {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let c = rng.random_range(2..=4usize);
    let mut templates = vec![Template::singleton()];
    for t in 0..rng.random_range(1..=3) {
        let k = rng.random_range(2..=4);
        templates.push(random_template(&mut rng, format!("t{t}_{k}"), k));
    }
    let spns = templates
        .iter()
        .map(|t| random_template_spn(&mut rng, t.num_nodes, c as u32))
        .collect();
    let classes = ClassSet::new((0..c).map(|k| format!("C{k}")).collect()).unwrap();
    let model = Model {
        format: 1,
        family: Default::default(),
        classes: classes.clone(),
        templates,
        spns,
        settings: serde_json::Value::Null,
        trained_on: vec![],
    };
    let n = rng.random_range(4..=24);
    let mut map = random_connected_map(n, rng.random_range(2..=4), rng.random_range(0..n), seed);
    map.classes = classes;
    for p in map.graph.node_weights_mut() {
        p.class = None;
    }
    let count = rng.random_range(1..=4);
    let decs = decompose_best(
        &map,
        &model.templates,
        &DecompositionParams {
            count,
            candidates: 3 * count,
            seed,
            ..DecompositionParams::default()
        },
    )
    .unwrap();
    Case {
        name: format!("s{seed}"),
        model,
        map,
        decs,
        // Every third structure is compiled to f64, every other one to scalar code.
        variants: vec![Variant {
            precision: if seed.is_multiple_of(3) {
                Precision::F64
            } else {
                Precision::F32
            },
            vectorisation: if seed % 2 == 1 {
                Vectorisation::Scalar
            } else {
                Vectorisation::Simd
            },
        }],
        vectors,
        seed,
    }
}

#[test]
fn random_structures_match_interpreter() {
    let total = env_usize("GRAPHSPN_FUZZ_STRUCTURES", STRUCTURES);
    let vectors = env_usize("GRAPHSPN_FUZZ_VECTORS", VECTORS);
    let seeds: Vec<u64> = (0..total as u64).collect();
    for batch in seeds.chunks(BATCH) {
        let cases: Vec<Case> = batch.iter().map(|&s| random_case(s, vectors)).collect();
        let modules = differential("structure_fuzz", &cases);
        // The batch must exercise both code paths of the generator: floor + sparse
        // block code (dense templates in linear space) and per-node code.
        let count = |marker: &str| {
            modules
                .iter()
                .filter(|(_, src)| src.contains(marker))
                .count()
        };
        let (lanes, per_node) = (count("_fwd(x: &[[V;"), count("_fwd(x: &[[f"));
        eprintln!(
            "of {} structures, {lanes} use block code and {per_node} per-node code",
            modules.len()
        );
        if modules.len() >= 8 {
            assert!(lanes > 0 && per_node > 0, "one code path is not fuzzed");
        }
    }
}
