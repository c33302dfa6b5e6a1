//! Structure fuzzing: random models (random templates via `Template::custom`, random
//! class counts, random layered or dense template SPNs with exact-zero and skewed
//! weights, one- and two-pass marginals) on random connected maps, compiled into one temporary crate, built, run
//! and compared with the interpreter. Seeds are printed with every failure.
//!
//! Scale up: `GRAPHSPN_FUZZ_STRUCTURES=5000` (built in batches of [`BATCH`] modules per
//! crate), `GRAPHSPN_FUZZ_VECTORS=N` evidence vectors per structure.

mod harness;

use graphspn::codegen::{Arithmetic, Precision, Vectorisation};
use graphspn::decompose::synthetic::random_connected_map;
use graphspn::decompose::{DecompositionParams, decompose_best};
use graphspn::learn::{DenseParams, Model, dense_structure, uniform_spn};
use graphspn::map::ClassSet;
use graphspn::spn::random::layered_spn;
use graphspn::spn::{Node, Spn};
use graphspn::template::Template;
use harness::{Case, Variant, differential, env_usize};
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

/// A random template SPN: a quarter of the time a layered SPN whose sums miss a
/// product each (no full cartesian segments, so no block structure) with positive
/// weights (per-node code in linear space); otherwise a layered SPN (per-node code) or,
/// half the time, a dense region structure with random sizes (block kernels in SIMD
/// lane groups), with some sum weights set to exactly 0 (one positive kept; weights
/// renormalised, as the interpreter requires), sometimes very skewed.
fn random_template_spn(rng: &mut ChaCha8Rng, vars: usize, classes: u32) -> Spn {
    let (layered, irregular) = (rng.random_bool(0.5), rng.random_bool(0.5));
    let mut spn = if layered && irregular {
        // Regions of two or more sums, positive weights: per-node linear code.
        let mut spn = layered_spn(rng.random(), vars, classes, rng.random_range(2..=3));
        drop_a_product(rng, &mut spn);
        spn
    } else if layered {
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
    let plain = layered && irregular;
    let zero_p = if !plain && rng.random_bool(0.5) {
        0.25
    } else {
        0.0
    };
    let skew = !plain && rng.random_bool(0.3);
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

/// Removes one product child (and its weight) from sums that have at least three,
/// never a product's last parent (so every node stays reachable): the SPN stays
/// complete and decomposable, but those sums no longer hold every tuple of a cartesian
/// product, which the block recogniser requires.
fn drop_a_product(rng: &mut ChaCha8Rng, spn: &mut Spn) {
    let mut parents = vec![0usize; spn.nodes.len()];
    for node in &spn.nodes {
        if let Node::Sum { children, .. } = node {
            children.iter().for_each(|&c| parents[c as usize] += 1);
        }
    }
    let products: Vec<bool> = spn
        .nodes
        .iter()
        .map(|n| matches!(n, Node::Product { .. }))
        .collect();
    for node in spn.nodes.iter_mut() {
        if let Node::Sum { children, weights } = node {
            let droppable: Vec<usize> = (0..children.len())
                .filter(|&i| products[children[i] as usize] && parents[children[i] as usize] > 1)
                .collect();
            if children.len() >= 3 && !droppable.is_empty() {
                let i = droppable[rng.random_range(0..droppable.len())];
                parents[children[i] as usize] -= 1;
                children.remove(i);
                weights.remove(i);
            }
        }
    }
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
        // Every third structure is compiled to f64, every other one to scalar code,
        // and every other f32 scalar one with the fixed-point kernel.
        variants: vec![{
            let (precision, vectorisation) = (
                if seed.is_multiple_of(3) {
                    Precision::F64
                } else {
                    Precision::F32
                },
                if seed % 2 == 1 {
                    Vectorisation::Scalar
                } else {
                    Vectorisation::Simd
                },
            );
            let fixed = precision == Precision::F32
                && vectorisation == Vectorisation::Scalar
                && (seed / 2).is_multiple_of(2);
            Variant {
                precision,
                vectorisation,
                arithmetic: if fixed {
                    Arithmetic::Fixed
                } else {
                    Arithmetic::Float
                },
            }
        }],
        vectors,
        seed,
    }
}

/// Templates compiled on each code path, over the generated modules: `[block code,
/// per-node linear, per-node log]`. A per-node template's forward function takes
/// scalar rows (`_fwd(x: &[[f32; ...`); in log space it starts by taking the rows'
/// logs (`ln_rows_*`).
fn code_paths(modules: &[(String, String)]) -> [usize; 3] {
    let mut paths = [0; 3];
    for (_, src) in modules {
        paths[0] += src.matches("_fwd(x: &[[V;").count();
        for (i, _) in src.match_indices("_fwd(x: &[[f") {
            let body = &src[i..];
            let end = body[1..].find("#[inline").map_or(body.len(), |e| e + 1);
            if body[..end].contains("ln_rows_") {
                paths[2] += 1;
            } else {
                paths[1] += 1;
            }
        }
    }
    paths
}

#[test]
fn random_structures_match_interpreter() {
    let total = env_usize("GRAPHSPN_FUZZ_STRUCTURES", STRUCTURES);
    let vectors = env_usize("GRAPHSPN_FUZZ_VECTORS", VECTORS);
    let seeds: Vec<u64> = (0..total as u64).collect();
    for batch in seeds.chunks(BATCH) {
        let cases: Vec<Case> = batch.iter().map(|&s| random_case(s, vectors)).collect();
        let modules = differential("structure_fuzz", &cases);
        // The batch must exercise every code path of the generator: floor + sparse
        // block code (dense templates in linear space), per-node code in linear space
        // and per-node code in log space (exact zeros or tiny values).
        let paths = code_paths(&modules);
        eprintln!(
            "of {} structures' templates: {} use block code, {} per-node linear code, {} per-node log code",
            modules.len(),
            paths[0],
            paths[1],
            paths[2]
        );
        if modules.len() >= 8 {
            assert!(
                paths.iter().all(|&n| n > 0),
                "a code path is not fuzzed: {paths:?}"
            );
        }
    }
}
