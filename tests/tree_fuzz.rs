//! Structure fuzzing of generated tree-mixture code: random class counts (2 to 12),
//! random maps (connected, disconnected, single places, long paths), random numbers of
//! trees, evidence exponents, mixings and potentials (up to the 1e6 ratio the model
//! check allows), compiled in every form (f32 / f64, scalar / SIMD) into one temporary
//! crate, run, and compared with `TreeInstance` and the interpreter on every vector and
//! with brute-force enumeration on maps of at most 8 places. The test asserts that the
//! structures it drew reach every code path of the generator and the driver (listed in
//! [`Paths`]). Seeds are printed with every failure.
//!
//! Scale up: `GRAPHSPN_FUZZ_STRUCTURES=500 GRAPHSPN_FUZZ_VECTORS=200`.

#[allow(dead_code)]
#[path = "../compiler/tests/harness/treemix.rs"]
mod brute;
mod harness;

use graphspn::codegen::{Arithmetic, Precision, Vectorisation};
use graphspn::family::ModelFamily;
use graphspn::map::{ClassSet, Place, TopoMap};
use graphspn::spn::Mixing;
use graphspn::treemix::{SpanningTrees, TreeInstance, TreeMixture};
use graphspn_runtime::__private::parallel_sweeps;
use harness::trees::{TreeCase, tree_differential};
use harness::{Variant, env_usize};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Random structures per CI run.
const STRUCTURES: usize = 40;
/// Evidence vectors per structure.
const VECTORS: usize = 120;

/// A random map of `n` places: a random forest of `parts` components (a long path
/// when `path`), plus up to `extra` random edges inside components.
fn random_map(
    rng: &mut ChaCha8Rng,
    n: usize,
    c: usize,
    parts: usize,
    path: bool,
    extra: usize,
) -> TopoMap {
    let id = |i: usize| 7 + 3 * i as u32;
    let places = (0..n)
        .map(|i| Place {
            id: id(i),
            class: None,
            placeholder: false,
            x: i as f64,
            y: 0.0,
        })
        .collect();
    // Component of place i: i % parts; each joins a random earlier place of its own.
    let mut edges = vec![];
    for i in 0..n {
        let same: Vec<usize> = (0..i).filter(|&j| j % parts == i % parts).collect();
        if let Some(&last) = same.last() {
            let j = if path {
                last
            } else {
                same[rng.random_range(0..same.len())]
            };
            edges.push((j, i));
        }
    }
    for _ in 0..rng.random_range(0..=extra) {
        let (a, b) = (rng.random_range(0..n), rng.random_range(0..n));
        if a != b && a % parts == b % parts {
            edges.push((a, b));
        }
    }
    TopoMap::new(
        format!("fuzz-{n}"),
        ClassSet::new((0..c).map(|k| format!("k{k}")).collect()).unwrap(),
        places,
        edges.into_iter().map(|(a, b)| (id(a), id(b))).collect(),
    )
    .unwrap()
}

/// A random model: symmetric potential and unary with entries spread over up to six
/// orders of magnitude (the model check's limit), or mild ones.
fn random_model(rng: &mut ChaCha8Rng, c: usize, trees: usize) -> TreeMixture {
    let spread = if rng.random_bool(0.3) { 6.0 } else { 1.0 };
    let draw = |rng: &mut ChaCha8Rng| 10f64.powf(-spread * rng.random::<f64>());
    let mut potential = vec![0.0; c * c];
    for a in 0..c {
        for b in a..c {
            let v = draw(rng);
            potential[a * c + b] = v;
            potential[b * c + a] = v;
        }
    }
    let unary = (0..c).map(|_| draw(rng)).collect();
    let model = TreeMixture {
        format: 1,
        family: ModelFamily::TreeMixture,
        classes: ClassSet::new((0..c).map(|k| format!("k{k}")).collect()).unwrap(),
        potential,
        unary,
        evidence_exponent: rng.random_range(1..=8),
        trees,
        mixing: if rng.random_bool(0.5) {
            Mixing::Posterior
        } else {
            Mixing::Average
        },
        settings: serde_json::Value::Null,
        trained_on: vec![],
    };
    model.check("fuzz").unwrap();
    model
}

/// The code paths a structure reaches; the test asserts every one was reached.
#[derive(Debug, Default)]
struct Paths {
    f32_scalar: usize,
    f32_simd: usize,
    f64_scalar: usize,
    f64_simd: usize,
    /// Class rows with padding lanes (SIMD, `C` not a multiple of the lanes).
    padded: usize,
    /// Class rows filling whole vectors (SIMD, `C` a multiple of the lanes).
    whole: usize,
    posterior: usize,
    average: usize,
    gamma_one: usize,
    gamma_more: usize,
    single_place: usize,
    several_roots: usize,
    deep: usize,
    one_tree: usize,
    /// SIMD value sweeps of 1, 2 and 4 forests side by side.
    side_by_side: [usize; 3],
    /// Scalar modules whose deepest entry point computes `φ` in each pass (no table).
    factor_rows: usize,
    /// `SoftF32` modules with fixed-point messages, and with `f32` messages (potentials
    /// too small for the fixed-point bound).
    fixed_messages: usize,
    float_messages: usize,
    brute_force: usize,
}

fn random_case(seed: u64, vectors: usize, paths: &mut Paths) -> TreeCase {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let c = match seed % 5 {
        0 => 8,
        1 => 4,
        _ => rng.random_range(2..=12),
    };
    // A wide map (many places, shallow spanning trees, 4 or 5 of them): SIMD code then
    // sweeps four forests side by side.
    let wide = seed % 11 == 5;
    let n = match seed % 7 {
        _ if wide => rng.random_range(48..=64),
        0 => 1,
        1 => rng.random_range(2..=8),
        _ => rng.random_range(2..=40),
    };
    let parts = if rng.random_bool(0.3) {
        rng.random_range(1..=n.clamp(1, 4))
    } else {
        1
    };
    let map = random_map(
        &mut rng,
        n,
        c,
        parts,
        seed % 9 == 2,
        if wide { 3 * n } else { n },
    );
    let t = rng.random_range(if wide { 4 } else { 1 }..=5);
    let model = random_model(&mut rng, c, t);
    let trees = SpanningTrees::covering(&map, t, seed).unwrap();
    let variant = Variant {
        precision: if seed.is_multiple_of(2) {
            Precision::F32
        } else {
            Precision::F64
        },
        vectorisation: if seed % 4 < 2 {
            Vectorisation::Simd
        } else {
            Vectorisation::Scalar
        },
        arithmetic: Arithmetic::Float,
    };
    match (variant.precision, variant.vectorisation) {
        (Precision::F32, Vectorisation::Scalar) => paths.f32_scalar += 1,
        (Precision::F32, Vectorisation::Simd) => paths.f32_simd += 1,
        (Precision::F64, Vectorisation::Scalar) => paths.f64_scalar += 1,
        (Precision::F64, Vectorisation::Simd) => paths.f64_simd += 1,
    }
    if variant.vectorisation == Vectorisation::Simd {
        let lanes = if variant.precision == Precision::F32 {
            8
        } else {
            4
        };
        if c % lanes == 0 {
            paths.whole += 1;
        } else {
            paths.padded += 1;
        }
        // Forests swept side by side for values: 4, 2, or 1 (see `parallel_sweeps`).
        let h = trees.forests.iter().map(|f| f.height()).max().unwrap_or(0) + 2;
        let mut left = t;
        while left > 0 {
            let q: usize = match parallel_sweeps(lanes, n, h as usize) {
                4 if left >= 4 => 4,
                p if p >= 2 && left >= 2 => 2,
                _ => 1,
            };
            paths.side_by_side[q.ilog2() as usize] += 1;
            left -= q;
        }
    }
    match model.mixing {
        Mixing::Posterior => paths.posterior += 1,
        Mixing::Average => paths.average += 1,
    }
    if model.evidence_exponent == 1 {
        paths.gamma_one += 1;
    } else {
        paths.gamma_more += 1;
    }
    paths.single_place += usize::from(n == 1);
    paths.several_roots += usize::from(trees.forests[0].roots().len() > 1);
    paths.deep += usize::from(trees.forests.iter().any(|f| f.height() >= 6));
    paths.one_tree += usize::from(t == 1);
    // Scalar variants of seeds 6 and 7 mod 8 get a stack budget below their deepest
    // entry point's table: that one computes `φ` in each pass.
    let factor_tables = seed % 8 < 4;
    let case = TreeCase {
        name: format!("s{seed}"),
        model,
        map,
        trees,
        // f32 scalar code also in the no-FPU targets' form (`SoftF32` rows, fixed-point
        // messages where the model's bound allows), within its bound.
        variants: if variant.precision == Precision::F32
            && variant.vectorisation == Vectorisation::Scalar
        {
            vec![variant, Variant::FIXED]
        } else {
            vec![variant]
        },
        vectors,
        seed,
        interpreter_every: 1,
        extreme_every: 5,
        factor_tables,
    };
    // Whether some entry point of the module computes `φ` in each pass.
    let src = case.source(&variant);
    let flags = src.find("FactorCache {").map(|i| &src[i..]).unwrap_or("");
    paths.factor_rows += usize::from(flags[..flags.find('}').unwrap_or(0)].contains("false"));
    if case
        .variants
        .iter()
        .any(|v| v.arithmetic == Arithmetic::Fixed)
    {
        let fixed = case.source(&Variant::FIXED).contains("FixedMatrices {");
        paths.fixed_messages += usize::from(fixed);
        paths.float_messages += usize::from(!fixed);
    }
    case
}

/// Brute-force enumeration of a small case: `TreeInstance` (which the generated code
/// was compared with on every vector) equals the exhaustive sums on a few vectors.
fn check_brute_force(case: &TreeCase) -> bool {
    let (n, c) = (case.map.num_places(), case.model.num_classes());
    if n > 8 || (c as f64).powi(n as i32) > 2e5 {
        return false;
    }
    let mut inst = TreeInstance::build(&case.model, &case.map, case.trees.clone()).unwrap();
    // Not the vectors scaled by 2^±110 or with 1e-30 rows (kinds 2 and 5): their
    // products (to the power γ ≤ 8) leave f64's range in the enumeration.
    let plain = |v: &usize| {
        (case.extreme_every == 0 || v % case.extreme_every != 1) && !matches!(v % 6, 2 | 5)
    };
    for (v, ev) in case
        .evidence()
        .iter()
        .enumerate()
        .filter(|(v, _)| plain(v))
        .take(6)
    {
        inst.set_all_evidence(ev).unwrap();
        let o = brute::oracle(&case.model, &case.trees, ev, &vec![None; n]);
        let m = inst.marginals().unwrap();
        let tag = format!("{} vector {v}", case.name);
        assert!(
            (m.mixed.log_likelihood - o.log_likelihood).abs()
                < 1e-9 * o.log_likelihood.abs().max(1.0),
            "{tag}: ll"
        );
        let want = match case.model.mixing {
            Mixing::Posterior => &o.posterior,
            Mixing::Average => &o.average,
        };
        for (a, b) in m.mixed.probs.iter().flatten().zip(want.iter().flatten()) {
            assert!((a - b).abs() < 1e-9, "{tag}: marginals {a} vs {b}");
        }
        let mpe = inst.mpe(&vec![None; n]).unwrap();
        assert!(
            (mpe.log_max_product - o.log_max_product).abs()
                < 1e-9 * o.log_max_product.abs().max(1.0),
            "{tag}: mpe"
        );
    }
    true
}

#[test]
fn random_tree_mixtures_match_tree_instance_interpreter_and_brute_force() {
    let structures = env_usize("GRAPHSPN_FUZZ_STRUCTURES", STRUCTURES);
    let vectors = env_usize("GRAPHSPN_FUZZ_VECTORS", VECTORS);
    let mut paths = Paths::default();
    let cases: Vec<TreeCase> = (0..structures as u64)
        .map(|seed| random_case(seed, vectors, &mut paths))
        .collect();
    for case in &cases {
        paths.brute_force += usize::from(check_brute_force(case));
    }
    for batch in cases.chunks(200) {
        tree_differential("tree_fuzz", batch);
    }
    eprintln!("paths reached: {paths:?}");
    if structures >= STRUCTURES {
        let Paths {
            f32_scalar,
            f32_simd,
            f64_scalar,
            f64_simd,
            padded,
            whole,
            posterior,
            average,
            gamma_one,
            gamma_more,
            single_place,
            several_roots,
            deep,
            one_tree,
            side_by_side: [sweep_1, sweep_2, sweep_4],
            factor_rows,
            fixed_messages,
            float_messages,
            brute_force,
        } = paths;
        for (what, count) in [
            ("f32 scalar", f32_scalar),
            ("f32 SIMD", f32_simd),
            ("f64 scalar", f64_scalar),
            ("f64 SIMD", f64_simd),
            ("padded SIMD rows", padded),
            ("whole SIMD rows", whole),
            ("posterior mixing", posterior),
            ("average mixing", average),
            ("γ = 1", gamma_one),
            ("γ > 1", gamma_more),
            ("a single place", single_place),
            ("several roots", several_roots),
            ("a deep tree", deep),
            ("one tree", one_tree),
            ("SIMD value sweeps of one forest", sweep_1),
            ("SIMD value sweeps of two forests side by side", sweep_2),
            ("SIMD value sweeps of four forests side by side", sweep_4),
            ("φ computed in each pass", factor_rows),
            ("fixed-point messages", fixed_messages),
            ("f32 messages on SoftF32 rows", float_messages),
            ("brute force", brute_force),
        ] {
            assert!(count > 0, "no fuzz structure reached: {what} ({paths:?})");
        }
    }
}
