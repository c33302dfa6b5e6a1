//! The runtime's fixtures (`runtime/tests/fixtures/`): generated modules of small maps
//! — every kind the generator emits: GraphSPN and tree mixture, `f32` and `f64`,
//! scalar and SIMD, float and fixed point — and what the brute-force oracle or
//! `TreeInstance` answers on them. With them the runtime's own tests run real generated
//! code without the generator, in seconds: a change to the runtime alone (its mutation
//! testing, docs/TESTING.md) is checked without rebuilding the compiler.
//!
//! This test regenerates every fixture and fails when a checked-in file differs;
//! `GRAPHSPN_UPDATE_FIXTURES=1 cargo test -p graphspn-compiler --test runtime_fixtures`
//! rewrites them.

mod harness;

use std::fmt::Write as _;
use std::path::PathBuf;

use graphspn_compiler::codegen::{
    Arithmetic, CodegenOptions, Precision, Vectorisation, generate, generate_trees_with_report,
};
use graphspn_compiler::decompose::Decomposition;
use graphspn_compiler::instance::ComponentInstance;
use graphspn_compiler::learn::{DenseParams, Model, dense_structure, uniform_spn};
use graphspn_compiler::map::{ClassId, TopoMap};
use graphspn_compiler::spn::{Mixing, Node};
use graphspn_compiler::template::Template;
use graphspn_compiler::treemix::{SpanningTrees, TreeInstance, TreeMixture};
use harness::codegen::{
    decompose, dense_model_with, grid, map, model, oracle, random_spn, randomise_weights, tiny,
};
use harness::instance::tiny_map;
use harness::treemix::random_model;
use petgraph::graph::NodeIndex;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn fixture_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../runtime/tests/fixtures")
}

fn options(precision: Precision, scalar: bool, arithmetic: Arithmetic) -> CodegenOptions {
    CodegenOptions {
        precision,
        vectorisation: if scalar {
            Vectorisation::Scalar
        } else {
            Vectorisation::Simd
        },
        arithmetic,
        model_label: "runtime fixture".into(),
        ..Default::default()
    }
}

/// The answers of a reference evaluator for one evidence vector (`None`: zero
/// likelihood).
struct Answers {
    ll: Option<f64>,
    labelled: Option<f64>,
    mpe: Option<f64>,
    marginals: Vec<Vec<f64>>,
}

/// A model family's reference evaluator: brute-force enumeration (GraphSPN on small
/// maps), the interpreter's component-wise evaluator (GraphSPN on maps too large to
/// enumerate) or `TreeInstance` (tree mixtures).
enum Reference {
    Spn(Model, Vec<Decomposition>),
    Components(Box<ComponentInstance>),
    Trees(Box<TreeInstance>),
}

impl Reference {
    fn answers(&mut self, e: &[Vec<f64>], labels: &[u16]) -> Answers {
        let finite = |x: f64| x.is_finite().then_some(x);
        match self {
            Reference::Spn(m, decs) => {
                let o = oracle(m, decs, e, labels);
                Answers {
                    ll: finite(o.ll),
                    labelled: finite(o.lll),
                    mpe: finite(o.mpe),
                    marginals: o.marg,
                }
            }
            Reference::Components(inst) => {
                inst.set_all_evidence(e).unwrap();
                Answers {
                    ll: inst.log_likelihood().ok().and_then(finite),
                    labelled: inst
                        .log_likelihood_labelled(&clamped(labels))
                        .ok()
                        .and_then(finite),
                    mpe: inst
                        .mpe(&vec![None; e.len()])
                        .ok()
                        .and_then(|m| finite(m.log_max_product)),
                    marginals: inst.marginals().unwrap().probs,
                }
            }
            Reference::Trees(inst) => {
                inst.set_all_evidence(e).unwrap();
                let fixed = clamped(labels);
                Answers {
                    ll: inst.log_likelihood().ok().and_then(finite),
                    labelled: inst.log_likelihood_labelled(&fixed).ok().and_then(finite),
                    mpe: inst
                        .mpe(&vec![None; e.len()])
                        .ok()
                        .and_then(|m| finite(m.log_max_product)),
                    marginals: inst.marginals().unwrap().mixed.probs,
                }
            }
        }
    }
}

/// Labels as clamped places (`u16::MAX`: unknown).
fn clamped(labels: &[u16]) -> Vec<Option<ClassId>> {
    labels
        .iter()
        .map(|&l| (l != u16::MAX).then_some(l))
        .collect()
}

struct Fixture {
    name: &'static str,
    source: String,
    places: usize,
    classes: usize,
    precision: Precision,
    /// The power `γ` the model raises evidence rows to (1 for GraphSPN).
    evidence_exponent: u32,
    reference: Reference,
}

fn spn_fixture(
    name: &'static str,
    (m, mp, decs): (Model, TopoMap, Vec<Decomposition>),
    opts: CodegenOptions,
) -> Fixture {
    let source = generate(&m, &mp, &decs, &opts).unwrap();
    Fixture {
        name,
        source,
        places: mp.num_places(),
        classes: mp.classes.len(),
        precision: opts.precision,
        evidence_exponent: 1,
        reference: Reference::Spn(m, decs),
    }
}

/// A map of `n` places and `c` classes whose first `hubs` places are each joined to
/// every other place (one hub: a star; two: shallow trees that differ in which hub each
/// place hangs from).
fn hub_map(n: usize, c: usize, hubs: usize) -> TopoMap {
    let mut m = tiny_map(n, c, 0);
    m.graph.clear_edges();
    for h in 0..hubs {
        for i in h + 1..n {
            m.graph.add_edge(NodeIndex::new(h), NodeIndex::new(i), ());
        }
    }
    m
}

/// Tree-mixture shape: places, classes, forests, evidence exponent, mixing, seed.
type TreeSpec = (usize, usize, usize, u32, Mixing, u64);

fn tree_fixture(name: &'static str, spec: TreeSpec, opts: CodegenOptions) -> Fixture {
    tree_fixture_with(name, spec, opts, |_| {})
}

/// [`tree_fixture`] with the random model changed by `edit` first.
fn tree_fixture_with(
    name: &'static str,
    spec: TreeSpec,
    opts: CodegenOptions,
    edit: impl Fn(&mut TreeMixture),
) -> Fixture {
    let (places, classes, .., seed) = spec;
    tree_fixture_on(name, tiny_map(places, classes, seed), spec, opts, edit)
}

/// [`tree_fixture_with`] on the map `mp` (of `spec`'s places and classes).
fn tree_fixture_on(
    name: &'static str,
    mp: TopoMap,
    (places, classes, trees, gamma, mixing, seed): TreeSpec,
    opts: CodegenOptions,
    edit: impl Fn(&mut TreeMixture),
) -> Fixture {
    let mut m = random_model(classes, trees, gamma, mixing, seed);
    edit(&mut m);
    let forests = SpanningTrees::covering(&mp, trees, seed).unwrap();
    let (source, _) = generate_trees_with_report(&m, &mp, &forests, &opts).unwrap();
    Fixture {
        name,
        source,
        places,
        classes,
        precision: opts.precision,
        evidence_exponent: m.evidence_exponent,
        reference: Reference::Trees(Box::new(TreeInstance::build(&m, &mp, forests).unwrap())),
    }
}

/// `opts` (SIMD) with the largest stack budget (a multiple of 8 bytes below the
/// default) that leaves no room for one-pass marginals: the two-pass form (a value pass,
/// then `posterior_pass` over lane groups) that large maps get.
fn two_pass(
    (m, mp, decs): &(Model, TopoMap, Vec<Decomposition>),
    mut opts: CodegenOptions,
) -> CodegenOptions {
    let default = opts.stack_budget();
    let mut two_pass = |budget: usize| {
        opts.max_stack_bytes = Some(budget);
        generate(m, mp, decs, &opts)
            .ok()
            .map(|src| src.contains("__private::posterior_pass("))
    };
    // Down in steps of 256 bytes while one-pass code still fits, then in steps of 8
    // through the last step (the two-pass window is narrow on a small map).
    let mut budget = default;
    while two_pass(budget - 256) == Some(false) {
        budget -= 256;
    }
    let found = (1..=32)
        .map(|k| budget - 8 * k)
        .find(|&b| two_pass(b) == Some(true))
        .unwrap_or_else(|| panic!("no two-pass budget below {budget}"));
    opts.max_stack_bytes = Some(found);
    opts
}

/// A map around a star with a tail and a triangle: room for Star, Three, Pair and
/// Singleton components.
fn star_map(classes: usize) -> TopoMap {
    map(
        7,
        classes,
        &[(0, 1), (0, 2), (0, 3), (0, 4), (4, 5), (5, 6), (1, 2)],
    )
}

/// The real model structure (dense region blocks) on map `g`, kept small: 2 sums per
/// region, `splits` random splits per region, symmetric or not.
fn dense_on(
    g: TopoMap,
    classes: usize,
    symmetric: bool,
    splits: usize,
    seed: u64,
) -> (Model, TopoMap, Vec<Decomposition>) {
    let params = DenseParams {
        decompositions: splits,
        sums: 2,
        ..Default::default()
    };
    let m = dense_model_with(classes, symmetric, &params, seed);
    let decs = (0..3)
        .map(|s| decompose(&g, &m.templates, seed + s))
        .collect();
    (m, g, decs)
}

/// [`dense_on`] a 7-place map with two triangles.
fn dense(
    classes: usize,
    symmetric: bool,
    splits: usize,
    seed: u64,
) -> (Model, TopoMap, Vec<Decomposition>) {
    let g = map(
        7,
        classes,
        &[
            (0, 1),
            (1, 2),
            (2, 3),
            (3, 4),
            (4, 5),
            (5, 6),
            (1, 3),
            (4, 6),
        ],
    );
    dense_on(g, classes, symmetric, splits, seed)
}

/// `inputs` with the weights of its template SPNs' sums changed by `edit` (seeded),
/// which is given whether the sum is over products and says whether it changed the
/// weights; a changed sum is renormalised.
fn reweighted(
    (mut m, mp, decs): (Model, TopoMap, Vec<Decomposition>),
    seed: u64,
    mut edit: impl FnMut(&mut ChaCha8Rng, bool, &mut [f64]) -> bool,
) -> (Model, TopoMap, Vec<Decomposition>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    for spn in &mut m.spns {
        let product: Vec<bool> = spn
            .nodes
            .iter()
            .map(|n| matches!(n, Node::Product { .. }))
            .collect();
        for node in &mut spn.nodes {
            if let Node::Sum { children, weights } = node {
                let over_products = children.iter().all(|&c| product[c as usize]);
                if edit(&mut rng, over_products, weights) {
                    let total: f64 = weights.iter().sum();
                    weights.iter_mut().for_each(|w| *w /= total);
                }
            }
        }
    }
    (m, mp, decs)
}

/// `inputs` with each sum weight of its template SPNs set to exactly 0 with probability
/// `p` (a sum's largest weight is kept), the rest renormalised.
fn sparsified(
    inputs: (Model, TopoMap, Vec<Decomposition>),
    p: f64,
    seed: u64,
) -> (Model, TopoMap, Vec<Decomposition>) {
    reweighted(inputs, seed, |rng, _, weights| {
        let keep = (0..weights.len())
            .max_by(|&a, &b| weights[a].total_cmp(&weights[b]))
            .unwrap_or(0);
        for (i, w) in weights.iter_mut().enumerate() {
            if i != keep && rng.random_bool(p) {
                *w = 0.0;
            }
        }
        true
    })
}

/// `inputs` with each weight of a sum over products in its template SPNs set, with
/// probability `p`, to the smallest weight of its sum (the rest renormalised), as
/// smoothed counts leave most of a trained model's weights: a block row's terms then
/// mostly sit at its floor.
fn floored(
    inputs: (Model, TopoMap, Vec<Decomposition>),
    p: f64,
    seed: u64,
) -> (Model, TopoMap, Vec<Decomposition>) {
    reweighted(inputs, seed, |rng, over_products, weights| {
        if over_products {
            let floor = weights.iter().copied().fold(f64::INFINITY, f64::min);
            for w in weights.iter_mut() {
                if rng.random_bool(p) {
                    *w = floor;
                }
            }
        }
        over_products
    })
}

/// Random layered SPNs (exact-zero weights when `zeros`) on the star map.
fn layered(classes: usize, zeros: bool, seed: u64) -> (Model, TopoMap, Vec<Decomposition>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let templates = vec![
        Template::star(),
        Template::three(),
        Template::pair(),
        Template::singleton(),
    ];
    let spns = templates
        .iter()
        .map(|t| random_spn(&mut rng, t.num_nodes, classes, zeros, !zeros))
        .collect();
    let m = model(classes, templates, spns);
    let g = star_map(classes);
    let decs = (0..4)
        .map(|s| decompose(&g, &m.templates, seed + s))
        .collect();
    (m, g, decs)
}

/// Pair and Singleton SPNs of 10 classes (the COLD class count: SIMD code loads rows in
/// blocks of 8 classes plus a remainder) on a 4 × 3 grid (a full lane group of 8
/// Singletons).
fn ten_classes(seed: u64) -> (Model, TopoMap, Vec<Decomposition>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let templates = vec![Template::pair(), Template::singleton()];
    let spns = templates
        .iter()
        .map(|t| random_spn(&mut rng, t.num_nodes, 10, false, false))
        .collect();
    let m = model(10, templates, spns);
    let g = grid(4, 3, 10);
    let decs = (0..3)
        .map(|s| decompose(&g, &m.templates, seed + s))
        .collect();
    (m, g, decs)
}

/// Dense Pair SPNs (block structure: SIMD lane groups) and uniform Singletons, 2
/// classes, on a 4 × 3 grid: more than 8 distinct Pair components, so more than one
/// lane group.
fn dense_pairs(seed: u64) -> (Model, TopoMap, Vec<Decomposition>) {
    let params = DenseParams {
        sums: 2,
        ..Default::default()
    };
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut pair = dense_structure(2, 2, &params, seed).unwrap();
    randomise_weights(&mut pair, &mut rng);
    let spns = vec![pair, uniform_spn(1, 2).unwrap()];
    let m = model(2, vec![Template::pair(), Template::singleton()], spns);
    let g = grid(4, 3, 2);
    let decs = (0..4)
        .map(|s| decompose(&g, &m.templates, seed + s))
        .collect();
    (m, g, decs)
}

/// [`spn_fixture`] against the component-wise evaluator, for maps whose labellings are
/// too many to enumerate.
fn components_fixture(
    name: &'static str,
    (m, mp, decs): (Model, TopoMap, Vec<Decomposition>),
    opts: CodegenOptions,
) -> Fixture {
    let source = generate(&m, &mp, &decs, &opts).unwrap();
    let reference = ComponentInstance::build(&m, &mp, decs).unwrap();
    Fixture {
        name,
        source,
        places: mp.num_places(),
        classes: mp.classes.len(),
        precision: opts.precision,
        evidence_exponent: 1,
        reference: Reference::Components(Box::new(reference)),
    }
}

/// Every fixture: each kind of module the generator emits.
fn fixtures() -> Vec<Fixture> {
    use Arithmetic::{Fixed, Float};
    use Precision::{F32, F64};
    vec![
        spn_fixture("spn_tiny_simd_f32", tiny(), options(F32, false, Float)),
        components_fixture(
            "spn_ten_simd_f32",
            ten_classes(31),
            options(F32, false, Float),
        ),
        components_fixture(
            "spn_ten_simd_f64",
            ten_classes(32),
            options(F64, false, Float),
        ),
        {
            let inputs = dense_pairs(34);
            let opts = two_pass(&inputs, options(F32, false, Float));
            spn_fixture("spn_grid_simd_f32_two_pass", inputs, opts)
        },
        spn_fixture(
            "spn_dense_simd_f32",
            dense(2, true, 1, 5),
            options(F32, false, Float),
        ),
        spn_fixture(
            "spn_dense_simd_f64",
            dense(2, false, 3, 8),
            options(F64, false, Float),
        ),
        spn_fixture(
            "spn_dense_scalar_f32",
            dense(2, false, 2, 7),
            options(F32, true, Float),
        ),
        spn_fixture(
            "spn_dense_fixed",
            dense(2, true, 1, 6),
            options(F32, true, Fixed),
        ),
        // Four classes: the fixed-point functions keep their adjoints scaled (a place's
        // rows by 2, blocks by more), which two classes never need.
        components_fixture(
            "spn_dense_four_fixed",
            dense(4, true, 1, 9),
            options(F32, true, Fixed),
        ),
        // Half the weights exact zeros: the Three and the Pair have one-hot assignments
        // of value 0 and go to log space. A state's fused rows then keep every normal
        // entry: case 8's entries of 1e-30 decide its likelihood.
        components_fixture(
            "spn_floored_star_fixed",
            floored(dense_on(star_map(4), 4, true, 1, 10), 0.7, 10),
            options(F32, true, Fixed),
        ),
        components_fixture(
            "spn_sparse_scalar_f32",
            sparsified(dense(4, true, 1, 9), 0.5, 9),
            options(F32, true, Float),
        ),
        spn_fixture(
            "spn_layered_scalar_f64",
            layered(2, true, 11),
            options(F64, true, Float),
        ),
        spn_fixture(
            "spn_layered_simd_f32",
            layered(3, false, 12),
            options(F32, false, Float),
        ),
        tree_fixture(
            "trees_scalar_f32",
            (7, 3, 2, 1, Mixing::Posterior, 21),
            options(F32, true, Float),
        ),
        tree_fixture(
            "trees_simd_f32",
            (8, 4, 3, 2, Mixing::Average, 22),
            options(F32, false, Float),
        ),
        tree_fixture(
            "trees_scalar_f64",
            (6, 3, 3, 2, Mixing::Average, 23),
            options(F64, true, Float),
        ),
        tree_fixture(
            "trees_simd_f64",
            (7, 6, 2, 1, Mixing::Posterior, 24),
            options(F64, false, Float),
        ),
        tree_fixture(
            "trees_fixed",
            (8, 3, 2, 1, Mixing::Posterior, 25),
            options(F32, true, Fixed),
        ),
        // A potential of 2e-6: fixed-point messages would exceed their error bound, so
        // the no-FPU code keeps them in `SoftF32` floats.
        tree_fixture_with(
            "trees_fixed_float_messages",
            (7, 3, 2, 1, Mixing::Posterior, 26),
            options(F32, true, Fixed),
            |m| {
                m.potential[1] = 2e-6;
                m.potential[3] = 2e-6;
            },
        ),
        // A hub: the centre's belief is the product of 64 messages, whose entries
        // (about 1/6 each) would leave the `f32` range without a renormalisation after
        // each factor.
        tree_fixture_on(
            "trees_hub_scalar_f32",
            hub_map(65, 6, 1),
            (65, 6, 1, 1, Mixing::Average, 27),
            options(F32, true, Float),
            |_| {},
        ),
        // Seven shallow forests on SIMD: four value sweeps side by side, then two, then
        // one (`parallel_sweeps` = 4 needs four stacks of rows within the places).
        tree_fixture_on(
            "trees_two_hubs_simd_f32",
            hub_map(24, 3, 2),
            (24, 3, 7, 1, Mixing::Posterior, 28),
            options(F32, false, Float),
            |_| {},
        ),
        // Equal neighbours cost 1e-6, so on case 8 (the hubs of classes 0 and 1, every
        // other place of class 0) a forest's likelihood falls by 13.8 nats for each
        // place it hangs from hub 0: the forests' values lie farther apart than the
        // `f32` range, and marginals must mix them relative to the largest.
        tree_fixture_on(
            "trees_two_hubs_scalar_f32",
            hub_map(24, 3, 2),
            (24, 3, 7, 3, Mixing::Posterior, 29),
            options(F32, true, Float),
            sharp_potentials,
        ),
        // The same potentials with `γ = 1`: on case 8 each hub's evidence puts two
        // classes `1e-30` (`2^-100`) below its own, and its 22 or 23 neighbours, all of
        // its own class, overturn that. SIMD hosts once flushed entries below `2^-80`
        // (log-likelihood -132.57 where -102.21 is exact), and the streaming state's
        // rows dropped them on every target; both now keep every normal entry.
        tree_fixture_on(
            "trees_sharp_hubs_simd_f32",
            hub_map(24, 3, 2),
            (24, 3, 7, 1, Mixing::Posterior, 30),
            options(F32, false, Float),
            sharp_potentials,
        ),
        tree_fixture_on(
            "trees_sharp_hubs_scalar_f32",
            hub_map(24, 3, 2),
            (24, 3, 7, 1, Mixing::Posterior, 30),
            options(F32, true, Float),
            sharp_potentials,
        ),
    ]
}

/// Potentials `1e-6` for equal neighbours and `1` otherwise (3 classes).
fn sharp_potentials(m: &mut TreeMixture) {
    for (i, v) in m.potential.iter_mut().enumerate() {
        *v = if i % 4 == 0 { 1e-6 } else { 1.0 };
    }
}

/// Evidence of kind `kind`: random rows, rows with exact zeros, tiny values (scaled far
/// below 1), uniform rows, all ones.
fn evidence(rng: &mut ChaCha8Rng, n: usize, c: usize, kind: usize) -> Vec<Vec<f64>> {
    (0..n)
        .map(|p| {
            let mut row: Vec<f64> = (0..c)
                .map(|k| match kind {
                    0 | 1 => rng.random_range(0.02..1.0),
                    2 if (p + k) % 3 == 0 => 0.0,
                    2 => rng.random_range(0.1..2.0),
                    3 => rng.random_range(1e-30..1e-20),
                    4 => 0.5,
                    _ => 1.0,
                })
                .collect();
            if row.iter().all(|&v| v == 0.0) {
                row[0] = 0.25;
            }
            row
        })
        .collect()
}

/// `v · 2^k` in two steps, each exact in `f64` unless the result is subnormal (`2^±1035`
/// alone is out of range).
fn times_pow2(v: f64, k: i32) -> f64 {
    v * 2f64.powi(k / 2) * 2f64.powi(k - k / 2)
}

/// The fixture's expected-answers file: see `runtime/tests/generated_fixtures.rs`.
fn expected(f: &mut Fixture) -> String {
    let (n, c) = (f.places, f.classes);
    let mut rng = ChaCha8Rng::seed_from_u64(2026);
    let round = |v: f64| match f.precision {
        Precision::F32 => v as f32 as f64,
        Precision::F64 => v,
    };
    let mut cases: Vec<Vec<Vec<f64>>> = (0..6)
        .map(|kind| {
            evidence(&mut rng, n, c, kind)
                .into_iter()
                .map(|r| r.into_iter().map(round).collect())
                .collect()
        })
        .collect();
    // Case 6: the product of cases 0 and 1, what a state holds after `set_all(case 0)`
    // and `observe` of each row of case 1.
    let product = cases[0]
        .iter()
        .zip(&cases[1])
        .map(|(a, b)| a.iter().zip(b).map(|(x, y)| x * y).collect())
        .collect();
    cases.push(product);
    // Case 7: case 0 scaled by `2^-k`, every entry below the smallest normal value of
    // the precision. It must answer like its rows scaled back (exactly), its log values
    // shifted by `-n·γ·k·ln 2`; the reference answers the rows scaled back
    // (the product of a few such rows leaves even the `f64` range).
    let k_tiny = match f.precision {
        Precision::F32 => 135,
        Precision::F64 => 1035,
    };
    let tiny: Vec<Vec<f64>> = cases[0]
        .iter()
        .map(|r| r.iter().map(|&v| round(times_pow2(v, -k_tiny))).collect())
        .collect();
    let tiny_case = cases.len();
    cases.push(tiny);
    // Case 8: sharp rows, place 1 of class 1 and every other place of class 0, the
    // other entries 1e-30: forests of a tree mixture whose potentials forbid equal
    // neighbours then have likelihoods hundreds of nats apart (`trees_two_hubs_scalar_f32`).
    let sharp = (0..n)
        .map(|p| {
            let class = usize::from(p == 1 && c > 1);
            (0..c)
                .map(|k| if k == class { 1.0 } else { round(1e-30) })
                .collect()
        })
        .collect();
    cases.push(sharp);
    let mut out = String::new();
    let _ = writeln!(out, "places {n} classes {c}");
    let num = |x: Option<f64>| x.map_or("zero".to_string(), |v| format!("{v:e}"));
    for (k, e) in cases.iter().enumerate() {
        let labels: Vec<u16> = (0..n)
            .map(|p| match (p + k) % 3 {
                0 => u16::MAX,
                _ => ((p * 7 + k) % c) as u16,
            })
            .collect();
        let a = if k == tiny_case {
            let back: Vec<Vec<f64>> = e
                .iter()
                .map(|r| r.iter().map(|&v| times_pow2(v, k_tiny)).collect())
                .collect();
            let shift = -(n as f64)
                * f64::from(f.evidence_exponent)
                * f64::from(k_tiny)
                * std::f64::consts::LN_2;
            let mut a = f.reference.answers(&back, &labels);
            for v in [&mut a.ll, &mut a.labelled, &mut a.mpe] {
                *v = v.map(|x| x + shift);
            }
            a
        } else {
            f.reference.answers(e, &labels)
        };
        let _ = writeln!(out, "case {k}");
        let row = |v: &[f64]| v.iter().map(|x| format!(" {x:e}")).collect::<String>();
        let _ = writeln!(out, "evidence{}", row(&e.concat()));
        let labels: String = labels.iter().map(|l| format!(" {l}")).collect();
        let _ = writeln!(out, "labels{labels}");
        let _ = writeln!(out, "log_likelihood {}", num(a.ll));
        let _ = writeln!(out, "labelled {}", num(a.labelled));
        let _ = writeln!(out, "mpe {}", num(a.mpe));
        let _ = writeln!(out, "marginals{}", row(&a.marginals.concat()));
    }
    out
}

#[test]
fn runtime_fixtures_are_what_the_generator_emits() {
    let update = std::env::var_os("GRAPHSPN_UPDATE_FIXTURES").is_some();
    let dir = fixture_dir();
    let mut stale = vec![];
    let mut written = std::collections::BTreeSet::new();
    for mut f in fixtures() {
        let files = [
            (format!("{}.rs", f.name), f.source.clone()),
            (format!("{}.expected", f.name), expected(&mut f)),
        ];
        for (file, text) in files {
            let path = dir.join(&file);
            written.insert(file.clone());
            if std::fs::read_to_string(&path).ok().as_deref() == Some(text.as_str()) {
                continue;
            }
            if update {
                std::fs::create_dir_all(&dir).unwrap();
                std::fs::write(&path, text).unwrap();
            } else {
                stale.push(file);
            }
        }
    }
    // A file of a fixture no longer generated is stale too (removed by an update).
    for entry in std::fs::read_dir(&dir).unwrap() {
        let name = entry.unwrap().file_name().to_string_lossy().into_owned();
        if !written.contains(&name) {
            if update {
                std::fs::remove_file(dir.join(&name)).unwrap();
            } else {
                stale.push(name);
            }
        }
    }
    assert!(
        stale.is_empty(),
        "runtime fixtures out of date: {stale:?}; rewrite them with\n  \
         GRAPHSPN_UPDATE_FIXTURES=1 cargo test -p graphspn-compiler --test runtime_fixtures"
    );
}
