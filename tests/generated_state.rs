//! The streaming `State` of generated modules of both model families (GraphSPN and tree
//! mixture) against the stateless functions and the interpreter: random sequences of
//! `set_evidence` / `observe` / `clear_evidence` (rows with exact zeros, 1e-30 scales,
//! one-hot rows, rows of ones, invalid rows that must be rejected without changing
//! anything) on the demo floor and three COLD maps including the 230-place one, in
//! `f32` (scalar and SIMD) and `f64`.
//!
//! After every step the generated binary compares the state's log-likelihood,
//! marginals, one place's `marginal` and MPE value with the stateless functions on
//! the state's evidence; every few steps it also writes the state's evidence and its
//! answers, which the interpreter then checks ([`harness::check_case`];
//! [`harness::trees::check_tree_case`] for tree mixtures: `TreeInstance` too). A long
//! run of 100,000 updates on the 230-place map (each family) checks that the cache does
//! not drift.
mod harness;

use std::path::PathBuf;
use std::process::Command;

use graphspn::decompose::{DecompositionParams, decompose_best};
use graphspn::learn::Model;
use graphspn::treemix::{SpanningTrees, TreeMixture};
use harness::trees::{TreeCase, check_tree_case};
use harness::{Case, Variant, build_crate_with, check_case, env_usize, stride};

/// Updates per sequence.
const STEPS: usize = 1_000;
/// Updates of the drift run on the 230-place map.
const DRIFT_STEPS: usize = 100_000;

/// The binary: per module, `STEPS` seeded random updates (seed and counts from the
/// command line), checks against the stateless functions after each, and the
/// snapshots (state evidence and answers) in the `.ev` / `.out` format of the
/// differential harness.
const MAIN: &str = r#"
use graphspn_runtime::{CompiledMap, EvidenceError};
use std::io::Write;

struct SplitMix(u64);
impl SplitMix {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn unit(&mut self) -> f64 { (self.next() >> 11) as f64 / (1u64 << 53) as f64 }
    fn below(&mut self, n: usize) -> usize { (self.next() % n as u64) as usize }
}

trait Num: Copy + Into<f64> { fn from_f64(x: f64) -> Self; }
impl Num for f32 { fn from_f64(x: f64) -> Self { x as f32 } }
impl Num for f64 { fn from_f64(x: f64) -> Self { x } }

fn close(a: f64, b: f64, tol: f64) -> bool { a == b || (a - b).abs() <= tol * b.abs().max(1.0) }

fn run<M: CompiledMap>(dir: &std::path::Path, name: &str)
where
    M::Scalar: Num,
{
    let args: Vec<String> = std::env::args().collect();
    let seed: u64 = args[2].parse::<u64>().unwrap() + u64::from(name.starts_with("drift"));
    let (steps, every, tol) = if name.starts_with("drift") {
        (args[4].parse::<usize>().unwrap(), usize::MAX, 1e-4)
    } else {
        (args[3].parse::<usize>().unwrap(), if M::NUM_PLACES > 150 { 10 } else { 4 }, if name.ends_with("f64_scalar") || name.ends_with("f64") { 1e-9 } else { 1e-4 })
    };
    let (n, c) = (M::NUM_PLACES, M::NUM_CLASSES);
    let mut rng = SplitMix(seed);
    // A new state (all zeros in memory) reads as rows of ones, and an update as its
    // very first call agrees with the stateless functions.
    let one = M::Scalar::from_f64(1.0);
    assert!(M::state_evidence(&M::NEW_STATE).iter().all(|r| r.as_ref().iter().all(|&x| x == one)), "{name}: a new state's rows are not all ones");
    {
        let mut t = M::NEW_STATE;
        let mut first = M::ZERO_ROW;
        for k in 0..c { first.as_mut()[k] = M::Scalar::from_f64(0.05 + rng.unit()); }
        let p = rng.below(n);
        M::observe(&mut t, p, &first).expect("first observe");
        let ll: f64 = M::state_log_likelihood(&mut t).expect("state ll").into();
        let ev: Vec<M::Row> = M::state_evidence(&t).to_vec();
        let m = first.as_ref().iter().map(|&x| Into::<f64>::into(x)).fold(0.0, f64::max);
        let top = ev[p].as_ref().iter().map(|&x| Into::<f64>::into(x)).fold(0.0, f64::max);
        for (q, r) in ev.iter().enumerate() {
            for (k, &a) in r.as_ref().iter().enumerate() {
                let want = if q == p { Into::<f64>::into(first.as_ref()[k]) / m } else { 1.0 };
                let got = if q == p { Into::<f64>::into(a) / top } else { Into::<f64>::into(a) };
                assert!((got - want).abs() <= 1e-6, "{name}: first observe: place {q} class {k}: {got} vs {want}");
            }
        }
        // The fused row is the observation scaled by a power of two; the state's
        // log-likelihood is that of the observation itself.
        assert_eq!((top / m).log2().fract(), 0.0, "{name}: first observe: scaled by {}", top / m);
        let sl: f64 = Into::<f64>::into(M::log_likelihood(&ev).expect("stateless ll")) + f64::from(M::EVIDENCE_EXPONENT) * (m / top).ln();
        assert!(close(ll, sl, tol), "{name}: first observe on a new state: {ll} vs {sl}");
    }
    let mut s = M::NEW_STATE;
    let mut marg = vec![M::ZERO_ROW; n];
    let mut full = vec![M::ZERO_ROW; n];
    let mut lab = vec![0u16; n];
    let mut row = M::ZERO_ROW;
    let (mut rejected, mut snapshots) = (0usize, 0usize);
    // Per place and class `ln` of the evidence the state must hold: the row last set,
    // times every observation since, in f64.
    let mut fused = vec![vec![0.0f64; c]; n];
    let mut evs: Vec<u8> = Vec::new();
    let mut out: Vec<u8> = Vec::new();
    for step in 0..steps {
        let p = rng.below(n);
        let kind = rng.below(7);
        for k in 0..c {
            let x = match kind {
                0 => 1e-6 + rng.unit(),
                1 => if k != 0 && rng.unit() < 0.5 { 0.0 } else { 0.01 + rng.unit() },
                2 => 1e-30 * (1.0 + 9.0 * rng.unit()),
                3 => if k == 0 { 1.0 } else { 0.0 },
                4 => 1.0,
                5 => 0.0, // all zero: must be rejected
                _ => if k == 1 { f64::NAN } else { 0.5 }, // NaN: must be rejected
            };
            row.as_mut()[k] = M::Scalar::from_f64(x);
        }
        if kind == 3 { row.as_mut().rotate_right(rng.below(c)); }
        let before = M::state_log_likelihood(&mut s).map(Into::<f64>::into);
        let op = rng.below(3);
        let r = match op {
            0 => M::set_evidence(&mut s, p, &row),
            1 => M::observe(&mut s, p, &row),
            _ => { if kind >= 5 { Err(EvidenceError::ZeroLikelihood) } else { M::clear_evidence(&mut s, p) } }
        };
        if kind >= 5 || (op == 1 && r.is_err()) {
            assert!(r.is_err(), "{name} step {step}: an invalid row was accepted");
            let after = M::state_log_likelihood(&mut s).map(Into::<f64>::into);
            assert_eq!(before, after, "{name} step {step}: a rejected update changed the state");
            rejected += 1;
            continue;
        }
        r.unwrap_or_else(|e| panic!("{name} step {step}: update failed: {e}"));
        for (k, l) in fused[p].iter_mut().enumerate() {
            let x: f64 = row.as_ref()[k].into();
            match op {
                0 => *l = x.ln(),
                1 => *l += x.ln(),
                _ => *l = 0.0,
            }
        }
        let last = step + 1 == steps;
        if !(last || step < 1000 || step % 1000 == 0) { continue; }
        let ll = M::state_log_likelihood(&mut s).expect("state ll").into();
        M::state_marginals(&mut s, &mut marg).expect("state marginals");
        let mv: f64 = M::state_mpe(&mut s, &mut lab).expect("state mpe").into();
        let evidence: Vec<M::Row> = M::state_evidence(&s).to_vec();
        // The stateless log-likelihood of the state's rows, plus what each row lies below
        // the exact product of its observations (to the power `γ`): the log-likelihood of
        // that product.
        let offset: f64 = (0..n).map(|q| {
            let best = fused[q].iter().cloned().fold(f64::NEG_INFINITY, f64::max);
            let held = evidence[q].as_ref().iter().map(|&x| Into::<f64>::into(x)).fold(0.0, f64::max);
            best - held.ln()
        }).sum::<f64>() * f64::from(M::EVIDENCE_EXPONENT);
        let sl: f64 = Into::<f64>::into(M::log_likelihood(&evidence).expect("stateless ll")) + offset;
        M::marginals(&evidence, &mut full).expect("stateless marginals");
        let smv: f64 = M::mpe(&evidence, &mut vec![0u16; n]).expect("stateless mpe").into();
        assert!(close(ll, sl, tol), "{name} step {step}: state ll {ll} vs stateless {sl}");
        assert!(close(mv, smv + offset, tol), "{name} step {step}: state mpe {mv} vs stateless {smv} + {offset}");
        let q = rng.below(n);
        let mut one = M::ZERO_ROW;
        M::state_marginal(&mut s, q, &mut one).expect("state marginal");
        for p in 0..n {
            for k in 0..c {
                let (a, b): (f64, f64) = (marg[p].as_ref()[k].into(), full[p].as_ref()[k].into());
                assert!((a - b).abs() <= tol, "{name} step {step}: marginal of place {p} class {k}: state {a} vs stateless {b}");
            }
        }
        for k in 0..c {
            let (a, b): (f64, f64) = (one.as_ref()[k].into(), marg[q].as_ref()[k].into());
            assert!((a - b).abs() <= tol, "{name} step {step}: marginal({q}) class {k}: {a} vs marginals {b}");
        }
        if step % every == 0 || (every != usize::MAX && last) {
            // Snapshot for the interpreter: evidence, probe labels, answers.
            let probe: Vec<u16> = (0..n).map(|p| {
                let r = evidence[p].as_ref();
                let best = (0..c).fold(0, |b, k| if r[k].into() > r[b].into() { k } else { b });
                let v = snapshots;
                if (p + v) % 3 == 0 { best as u16 } else if (p + v) % 7 == 1 { ((best + 1) % c) as u16 } else { u16::MAX }
            }).collect();
            for p in 0..n { for k in 0..c { evs.extend_from_slice(&Into::<f64>::into(evidence[p].as_ref()[k]).to_le_bytes()); } }
            for &l in &probe { evs.extend_from_slice(&(l as f64).to_le_bytes()); }
            let pl: f64 = M::labelled_log_likelihood(&probe, &evidence).map_or(f64::NAN, Into::into);
            // The interpreter sees the state's rows: the values without the offset.
            out.extend_from_slice(&(ll - offset).to_le_bytes());
            out.extend_from_slice(&(mv - offset).to_le_bytes());
            out.extend_from_slice(&pl.to_le_bytes());
            for &l in &lab { out.extend_from_slice(&(l as f64).to_le_bytes()); }
            for r in &marg { for &x in r.as_ref() { out.extend_from_slice(&Into::<f64>::into(x).to_le_bytes()); } }
            snapshots += 1;
        }
    }
    let mut file = (snapshots as u64).to_le_bytes().to_vec();
    file.extend_from_slice(&evs);
    std::fs::write(dir.join(format!("{name}.ev")), file).expect("write evidence");
    std::fs::write(dir.join(format!("{name}.out")), out).expect("write results");
    let _ = writeln!(std::io::stdout(), "{name} {steps} {rejected} {snapshots}");
}

fn main() {
    let dir = std::path::PathBuf::from(std::env::args().nth(1).expect("data folder"));
    let dir = dir.as_path();
    std::thread::scope(|s| {
        DISPATCH
        s.spawn(|| run::<s_big_f32_scalar::Map>(dir, "drift_big_f32_scalar"));
        s.spawn(|| run::<t_big_f32_scalar::Map>(dir, "drift_tbig_f32_scalar"));
    });
}
"#;

#[test]
fn state_matches_stateless_and_interpreter() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let demo = root.join("generated/demo");
    let model = Model::load(demo.join("model.json")).unwrap();
    let tree_model = TreeMixture::load(demo.join("tree_model.json")).unwrap();
    let steps = env_usize("GRAPHSPN_STATE_STEPS", STEPS);
    let drift = env_usize("GRAPHSPN_STATE_DRIFT_STEPS", DRIFT_STEPS);
    let data = root.join("data/cold-topomaps");
    let mut maps = vec![
        (
            "demo".to_string(),
            graphspn::codegen::load_map(&demo.join("floor.json")).unwrap(),
        ),
        (
            "big".to_string(),
            graphspn::codegen::load_map(&demo.join("saarbrucken_seq2_night1.json")).unwrap(),
        ),
    ];
    for seq in ["Freiburg/seq1_cloudy1", "Stockholm/floor4_cloudy_a1"] {
        let map =
            graphspn::codegen::load_map(&data.join(seq)).unwrap_or_else(|e| panic!("{seq}: {e}"));
        maps.push((seq.replace('/', "_").to_lowercase(), map));
    }
    let mut cases = Vec::new();
    let mut tree_cases = Vec::new();
    for (i, (name, map)) in maps.into_iter().enumerate() {
        let decs = decompose_best(
            &map,
            &model.templates,
            &DecompositionParams {
                seed: i as u64,
                ..DecompositionParams::default()
            },
        )
        .unwrap();
        // f32 scalar (the microcontroller form) everywhere; the SIMD form and f64 on
        // the demo floor, f64 SIMD on the 230-place map.
        let variants = match i {
            0 => vec![Variant::F32_SCALAR, Variant::F32, Variant::F64_SCALAR],
            1 => vec![Variant::F32_SCALAR, Variant::F64],
            _ => vec![Variant::F32_SCALAR],
        };
        tree_cases.push(TreeCase {
            name: format!("t_{name}"),
            model: tree_model.clone(),
            trees: SpanningTrees::covering(&map, tree_model.trees, i as u64).unwrap(),
            map: map.clone(),
            variants: variants.clone(),
            vectors: 0,
            seed: 2000 + i as u64,
            interpreter_every: 1,
            extreme_every: 0,
            // The 230-place map's scalar modules compute `φ` in each pass.
            factor_tables: i != 1,
        });
        cases.push(Case {
            name: format!("s_{name}"),
            model: model.clone(),
            map,
            decs,
            variants,
            vectors: 0,
            seed: 1000 + i as u64,
        });
    }
    let dir = tempfile::tempdir().unwrap();
    let mut modules = Vec::new();
    for case in &cases {
        for v in &case.variants {
            let opts = graphspn::codegen::CodegenOptions {
                precision: v.precision,
                vectorisation: v.vectorisation,
                ..Default::default()
            };
            let src = graphspn::codegen::generate(&case.model, &case.map, &case.decs, &opts)
                .unwrap_or_else(|e| panic!("{}: {e}", case.module(v)));
            modules.push((case.module(v), src));
        }
    }
    for case in &tree_cases {
        for v in &case.variants {
            modules.push((case.module(v), case.source(v)));
        }
    }
    // The drift run (`drift_big_f32_scalar` in MAIN) reuses the 230-place map's
    // scalar f32 module (the microcontroller form).
    assert_eq!(cases[1].module(&Variant::F32_SCALAR), "s_big_f32_scalar");
    assert_eq!(
        tree_cases[1].module(&Variant::F32_SCALAR),
        "t_big_f32_scalar"
    );
    let bin = build_crate_with(dir.path(), "generated_state", &modules, MAIN);
    let seed = 42u64;
    eprintln!("state sequences: seed {seed}, {steps} steps per module, drift run {drift} steps");
    let run = Command::new(&bin)
        .arg(dir.path())
        .arg(seed.to_string())
        .arg(steps.to_string())
        .arg(drift.to_string())
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "state binary failed:\n{}",
        String::from_utf8_lossy(&run.stderr)
    );
    eprintln!("{}", String::from_utf8_lossy(&run.stdout));
    // The snapshots against the interpreter (and `TreeInstance`).
    let snapshots = |name: &str, n: usize, c: usize| {
        let ev = std::fs::read(dir.path().join(format!("{name}.ev"))).unwrap();
        let count = u64::from_le_bytes(ev[..8].try_into().unwrap()) as usize;
        assert!(count >= 20, "{name}: only {count} snapshots");
        let vals: Vec<f64> = ev[8..]
            .chunks_exact(8)
            .map(|b| f64::from_le_bytes(b.try_into().unwrap()))
            .collect();
        let per = n * c + n;
        let evs: Vec<Vec<Vec<f64>>> = (0..count)
            .map(|s| {
                (0..n)
                    .map(|p| vals[s * per + p * c..s * per + (p + 1) * c].to_vec())
                    .collect()
            })
            .collect();
        let out: Vec<f64> = std::fs::read(dir.path().join(format!("{name}.out")))
            .unwrap()
            .chunks_exact(8)
            .map(|b| f64::from_le_bytes(b.try_into().unwrap()))
            .collect();
        assert_eq!(out.len(), count * stride(n, c));
        (evs, out)
    };
    for case in &cases {
        let (n, c) = (case.map.num_places(), case.model.classes.len());
        for v in &case.variants {
            let name = case.module(v);
            let (evs, out) = snapshots(&name, n, c);
            let one = Case {
                name: case.name.clone(),
                model: case.model.clone(),
                map: case.map.clone(),
                decs: case.decs.clone(),
                variants: vec![*v],
                vectors: evs.len(),
                seed: case.seed,
            };
            check_case(&one, &evs, &[out]);
            eprintln!(
                "{name}: {} state snapshots agree with the interpreter",
                evs.len()
            );
        }
    }
    for case in &tree_cases {
        let (n, c) = (case.map.num_places(), case.model.num_classes());
        for v in &case.variants {
            let name = case.module(v);
            let (evs, out) = snapshots(&name, n, c);
            let one = TreeCase {
                name: case.name.clone(),
                model: case.model.clone(),
                map: case.map.clone(),
                trees: case.trees.clone(),
                variants: vec![*v],
                vectors: evs.len(),
                seed: case.seed,
                interpreter_every: 1,
                extreme_every: 0,
                factor_tables: case.factor_tables,
            };
            check_tree_case(&one, &evs, &[out]);
            eprintln!(
                "{name}: {} state snapshots agree with TreeInstance and the interpreter",
                evs.len()
            );
        }
    }
}

/// The generator's report gives the streaming state's size exactly (what `graphspn
/// compile` prints is the module's `STATE_BYTES`), for both families.
#[test]
fn reported_state_bytes_are_the_compiled_states() {
    use graphspn_compiler::codegen::{Builder, Vectorisation};
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("generated/demo");
    let big = "saarbrucken_seq2_night1.json";
    for (model, map, bytes) in [
        (
            "model.json",
            big,
            graphspn_generated::saarbrucken_seq2_night1::STATE_BYTES,
        ),
        (
            "model.json",
            "floor.json",
            graphspn_generated::demo_floor::STATE_BYTES,
        ),
        (
            "tree_model.json",
            big,
            graphspn_generated::saarbrucken_seq2_night1_trees::STATE_BYTES,
        ),
        (
            "tree_model.json",
            "floor.json",
            graphspn_generated::demo_floor_trees::STATE_BYTES,
        ),
    ] {
        // As `generated/build.rs` builds them: the tree mixture's forest count is the
        // model file's.
        let b = Builder::new(dir.join(model), dir.join(map))
            .vectorisation(Vectorisation::Simd)
            .seed(0);
        let b = if model == "model.json" { b.count(5) } else { b };
        let (_, report) = b.report_from_any(&b.load_any().unwrap()).unwrap();
        assert_eq!(report.state_bytes, bytes, "{model} on {map}");
    }
}
