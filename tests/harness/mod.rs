//! Shared harness of the cross-crate tests: builds generated modules into ONE
//! temporary crate (one module per map, so rustc runs once), runs its binary on
//! evidence files, and compares every answer with the interpreter evaluating the
//! instance GraphSPN.
#![allow(dead_code)]

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use graphspn::codegen::{Arithmetic, CodegenOptions, Precision, Vectorisation, generate};
use graphspn::decompose::Decomposition;
use graphspn::instance::Instance;
use graphspn::interpreter::{BATCH, Evaluator, Evidence, InferenceError};
use graphspn::learn::Model;
use graphspn::map::TopoMap;
use graphspn_runtime::EvidenceError;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

/// How one generated module of a [`Case`] is compiled.
#[derive(Clone, Copy, Debug)]
pub struct Variant {
    /// Scalar type of the generated code.
    pub precision: Precision,
    /// Scalar code (as on microcontrollers) or SIMD lane groups.
    pub vectorisation: Vectorisation,
    /// Float or fixed-point template kernels.
    pub arithmetic: Arithmetic,
}

impl Variant {
    /// `f32` code in SIMD lane groups (the host's form).
    pub const F32: Variant = Variant {
        precision: Precision::F32,
        vectorisation: Vectorisation::Simd,
        arithmetic: Arithmetic::Float,
    };
    /// `f64` code in SIMD lane groups.
    pub const F64: Variant = Variant {
        precision: Precision::F64,
        vectorisation: Vectorisation::Simd,
        arithmetic: Arithmetic::Float,
    };
    /// `f32` scalar code (the microcontroller form).
    pub const F32_SCALAR: Variant = Variant {
        precision: Precision::F32,
        vectorisation: Vectorisation::Scalar,
        arithmetic: Arithmetic::Float,
    };
    /// `f64` scalar code.
    pub const F64_SCALAR: Variant = Variant {
        precision: Precision::F64,
        vectorisation: Vectorisation::Scalar,
        arithmetic: Arithmetic::Float,
    };

    /// `f32` scalar code with the fixed-point kernel (targets without an FPU).
    pub const FIXED: Variant = Variant {
        precision: Precision::F32,
        vectorisation: Vectorisation::Scalar,
        arithmetic: Arithmetic::Fixed,
    };

    /// Module name suffix, e.g. `f32`, `f64_scalar`, `fixed`.
    fn suffix(&self) -> String {
        if self.arithmetic == Arithmetic::Fixed {
            return "fixed".into();
        }
        let p = match self.precision {
            Precision::F32 => "f32",
            Precision::F64 => "f64",
        };
        if self.vectorisation == Vectorisation::Scalar {
            format!("{p}_scalar")
        } else {
            p.to_string()
        }
    }

    /// Tolerance of the comparison: log-likelihoods relative, marginals absolute.
    pub fn tolerance(&self) -> f64 {
        match self.precision {
            Precision::F32 => 1e-4,
            Precision::F64 => 1e-9,
        }
    }
}

/// One map to compile and test: every variant is compiled into its own module, run
/// on the same evidence and compared with one interpreter evaluation per vector.
pub struct Case {
    /// Module name stem (a Rust identifier).
    pub name: String,
    /// The model.
    pub model: Model,
    /// The map.
    pub map: TopoMap,
    /// The decompositions.
    pub decs: Vec<Decomposition>,
    /// The generated modules (at least one).
    pub variants: Vec<Variant>,
    /// Number of random evidence vectors.
    pub vectors: usize,
    /// Seed of the evidence.
    pub seed: u64,
}

impl Case {
    /// Module name of one variant.
    pub fn module(&self, v: &Variant) -> String {
        format!("{}_{}", self.name, v.suffix())
    }
}

/// The number in environment variable `name`, or `default` when it is not set.
pub fn env_usize(name: &str, default: usize) -> usize {
    std::env::var(name)
        .ok()
        .map(|v| {
            v.parse()
                .unwrap_or_else(|_| panic!("{name}={v} is not a number"))
        })
        .unwrap_or(default)
}

/// Random evidence vectors including extremes; vector `v` uses kind `v % 6`:
/// uniform random, exact zeros, tiny (1e-30 scale), one-hot, uniform rows, mixed rows.
pub fn evidence(rng: &mut ChaCha8Rng, n: usize, c: usize, v: usize) -> Vec<Vec<f64>> {
    let row = |rng: &mut ChaCha8Rng, kind: usize| -> Vec<f64> {
        let mut r: Vec<f64> = match kind {
            0 => (0..c).map(|_| rng.random_range(1e-6..1.0)).collect(),
            1 => (0..c)
                .map(|_| {
                    if rng.random_bool(0.5) {
                        0.0
                    } else {
                        rng.random_range(0.01..1.0)
                    }
                })
                .collect(),
            2 => (0..c)
                .map(|_| 1e-30 * rng.random_range(1.0..10.0))
                .collect(),
            3 => {
                let k = rng.random_range(0..c);
                (0..c).map(|j| if j == k { 1.0 } else { 0.0 }).collect()
            }
            _ => vec![1.0; c],
        };
        if r.iter().all(|&x| x == 0.0) {
            let k = rng.random_range(0..c);
            r[k] = 1.0;
        }
        r
    };
    let kind = v % 6;
    (0..n)
        .map(|_| {
            let k = if kind == 5 {
                rng.random_range(0..5)
            } else {
                kind
            };
            row(rng, k)
        })
        .collect()
}

/// Labels for the labelled-likelihood check of vector `v` (`None` = unknown): every
/// third place gets its row's largest class, every seventh the next class (which may
/// have zero evidence, so some vectors take the zero-likelihood path), the rest none.
pub fn probe_labels(e: &[Vec<f64>], v: usize) -> Vec<Option<u32>> {
    e.iter()
        .enumerate()
        .map(|(p, row)| {
            let best = (0..row.len()).fold(0, |b, k| if row[k] > row[b] { k } else { b });
            if (p + v).is_multiple_of(3) {
                Some(best as u32)
            } else if (p + v) % 7 == 1 {
                Some(((best + 1) % row.len()) as u32)
            } else {
                None
            }
        })
        .collect()
}

/// The answers of module `M` (an `f32` module of this process, e.g. from
/// `graphspn-generated`) to evidence vectors `evs`, as the temporary crate's binary
/// writes them (per vector see [`stride`]; NaN on error).
pub fn in_process_answers<M: graphspn_runtime::CompiledMap<Scalar = f32>>(
    evs: &[Vec<Vec<f64>>],
) -> Vec<f64> {
    let (n, c) = (M::NUM_PLACES, M::NUM_CLASSES);
    let mut vals = Vec::with_capacity(evs.len() * stride(n, c));
    let mut e = vec![M::ZERO_ROW; n];
    let mut marg = vec![M::ZERO_ROW; n];
    let mut lab = vec![0u16; n];
    for (v, ev) in evs.iter().enumerate() {
        for (row, src) in e.iter_mut().zip(ev) {
            for (x, &s) in row.as_mut().iter_mut().zip(src) {
                *x = s as f32;
            }
        }
        let probe: Vec<u16> = probe_labels(ev, v)
            .into_iter()
            .map(|p| p.map_or(u16::MAX, |k| k as u16))
            .collect();
        let nan = f64::NAN;
        vals.push(M::log_likelihood(&e).map_or(nan, f64::from));
        vals.push(M::mpe(&e, &mut lab).map_or(nan, f64::from));
        vals.push(M::labelled_log_likelihood(&probe, &e).map_or(nan, f64::from));
        let ml = M::marginals(&e, &mut marg).map_or(nan, f64::from);
        let ll = vals[vals.len() - 3];
        assert!(
            (ml.is_nan() && ll.is_nan()) || (ml - ll).abs() <= 1e-5 * ll.abs().max(1.0),
            "marginals returned log-likelihood {ml}, log_likelihood {ll}"
        );
        vals.extend(lab.iter().map(|&l| f64::from(l)));
        vals.extend(
            marg.iter()
                .flat_map(|r| r.as_ref().iter().map(|&x| f64::from(x))),
        );
    }
    vals
}

/// Results per evidence vector: log-likelihood, MPE value, labelled log-likelihood
/// (NaN on error), then `n` MPE labels and `n × c` marginals.
pub fn stride(n: usize, c: usize) -> usize {
    3 + n + n * c
}

/// The temporary crate's main: for every module, reads `<name>.ev` (u64 count, then
/// per vector n × c evidence values and n probe labels, little-endian f64, unknown =
/// 65535), writes `<name>.out` (per vector: see [`stride`]); prints the query time.
/// Modules run in parallel threads.
const MAIN: &str = r#"
use graphspn_runtime::CompiledMap;
use std::io::Write;

fn run<M: CompiledMap>(dir: &std::path::Path, name: &str)
where
    M::Scalar: Into<f64> + FromF64,
{
    let (n, c) = (M::NUM_PLACES, M::NUM_CLASSES);
    let bytes = std::fs::read(dir.join(format!("{name}.ev"))).expect("evidence file");
    let count = u64::from_le_bytes(bytes[..8].try_into().unwrap()) as usize;
    let vals: Vec<f64> = bytes[8..].chunks_exact(8).map(|b| f64::from_le_bytes(b.try_into().unwrap())).collect();
    let per = n * c + n;
    assert_eq!(vals.len(), count * per);
    let mut evs = vec![vec![M::ZERO_ROW; n]; count];
    let mut probes = vec![vec![0u16; n]; count];
    for (v, (ev, probe)) in evs.iter_mut().zip(&mut probes).enumerate() {
        for p in 0..n {
            for k in 0..c {
                ev[p].as_mut()[k] = M::Scalar::from_f64(vals[v * per + p * c + k]);
            }
            probe[p] = vals[v * per + n * c + p] as u16;
        }
    }
    let mut out = Vec::with_capacity(count * (3 + n + n * c) * 8);
    let mut marg = vec![M::ZERO_ROW; n];
    let mut lab = vec![0u16; n];
    let start = std::time::Instant::now();
    for (ev, probe) in evs.iter().zip(&probes) {
        let ll = M::log_likelihood(ev).map_or(f64::NAN, Into::into);
        let mv = M::mpe(ev, &mut lab).map_or(f64::NAN, Into::into);
        let pl = M::labelled_log_likelihood(probe, ev).map_or(f64::NAN, Into::into);
        // `marginals` returns the log-likelihood too: the same value, or the same error.
        let ml: f64 = M::marginals(ev, &mut marg).map_or(f64::NAN, Into::into);
        let same = (ml.is_nan() && ll.is_nan()) || ml == ll || (ml - ll).abs() <= 1e-5 * ll.abs().max(1.0);
        assert!(same, "{name}: marginals returned log-likelihood {ml}, log_likelihood {ll}");
        out.extend_from_slice(&ll.to_le_bytes());
        out.extend_from_slice(&mv.to_le_bytes());
        out.extend_from_slice(&pl.to_le_bytes());
        for &l in &lab {
            out.extend_from_slice(&(l as f64).to_le_bytes());
        }
        for row in &marg {
            for &x in row.as_ref() {
                out.extend_from_slice(&Into::<f64>::into(x).to_le_bytes());
            }
        }
    }
    let secs = start.elapsed().as_secs_f64();
    // The streaming state on the same vectors: every 4th vector set whole, otherwise
    // a few of its rows streamed into the state; the state's answers must equal the
    // stateless functions on the state's evidence.
    let tol = if core::mem::size_of::<M::Scalar>() == 4 { 1e-4 } else { 1e-9 };
    let mut st = M::NEW_STATE;
    let (mut sm, mut fm) = (vec![M::ZERO_ROW; n], vec![M::ZERO_ROW; n]);
    for (v, ev) in evs.iter().enumerate().take(STATE_VECTORS) {
        if v % 4 == 0 {
            M::set_all(&mut st, ev).expect("state set_all");
        } else {
            for k in 0..3 {
                let p = (v * 7 + k * 13) % n;
                M::set_evidence(&mut st, p, &ev[p]).expect("state set_evidence");
            }
        }
        let e: Vec<M::Row> = M::state_evidence(&st).to_vec();
        let (sl, fl) = match (M::state_marginals(&mut st, &mut sm), M::marginals(&e, &mut fm)) {
            (Ok(a), Ok(b)) => (a, b),
            (Err(a), Err(b)) => { assert_eq!(a, b, "{name} vector {v}"); continue; }
            (a, b) => panic!("{name} vector {v}: state {a:?} vs stateless {b:?}"),
        };
        let (sl, fl): (f64, f64) = (sl.into(), fl.into());
        assert!((sl - fl).abs() <= tol * fl.abs().max(1.0), "{name} vector {v}: state ll {sl} vs stateless {fl}");
        for (a, b) in sm.iter().zip(&fm) {
            for (&x, &y) in a.as_ref().iter().zip(b.as_ref()) {
                let (x, y): (f64, f64) = (x.into(), y.into());
                assert!((x - y).abs() <= tol, "{name} vector {v}: state marginal {x} vs stateless {y}");
            }
        }
    }
    std::fs::write(dir.join(format!("{name}.out")), out).expect("write results");
    let _ = writeln!(std::io::stdout(), "{name} {count} {secs}");
}

/// Vectors streamed into the state (the first ones of each module).
const STATE_VECTORS: usize = 1000;

trait FromF64 { fn from_f64(x: f64) -> Self; }
impl FromF64 for f32 { fn from_f64(x: f64) -> Self { x as f32 } }
impl FromF64 for f64 { fn from_f64(x: f64) -> Self { x } }

fn main() {
    let dir = std::path::PathBuf::from(std::env::args().nth(1).expect("data folder"));
    let dir = dir.as_path();
    // One thread per module (the query times printed overlap).
    std::thread::scope(|s| {
        DISPATCH
    });
}
"#;

/// The release profile of the temporary crates: opt-level 1. Rust never reorders or
/// fuses float operations at any opt-level, so the results are those of an opt-level 3
/// build bit for bit (the firmware tests compare opt-level 3 builds); the straight-line
/// template functions of a dozen modules compile several times faster, which is most of
/// these tests' time.
const TEST_PROFILE: &str = "[profile.release]\nopt-level = 1\ndebug = false\n";

/// Shared target folder of the temporary crates (keeps the runtime's build cached).
fn target_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target/generated-tests")
}

/// Writes a crate holding every module, builds it in release and returns the binary.
/// Panics with rustc's messages if the build fails or warns.
pub fn build_crate(dir: &Path, crate_name: &str, modules: &[(String, String)]) -> PathBuf {
    build_crate_with(dir, crate_name, modules, MAIN)
}

/// [`build_crate`] with another `main` source: `DISPATCH` in it is replaced by one
/// `s.spawn(|| run::<module::Map>(dir, "module"));` line per module.
pub fn build_crate_with(
    dir: &Path,
    crate_name: &str,
    modules: &[(String, String)],
    main: &str,
) -> PathBuf {
    let runtime = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("runtime");
    std::fs::write(
        dir.join("Cargo.toml"),
        format!(
            "[package]\nname = \"{crate_name}\"\nversion = \"0.0.0\"\nedition = \"2024\"\n\n[dependencies]\ngraphspn-runtime = {{ path = {:?} }}\n\n[workspace]\n\n{TEST_PROFILE}",
            runtime.display().to_string()
        ),
    )
    .unwrap();
    temp_crate::use_workspace_cargo_config(Path::new(env!("CARGO_MANIFEST_DIR")), dir);
    std::fs::create_dir_all(dir.join("src")).unwrap();
    let mut mods = String::new();
    let mut dispatch = String::new();
    for (name, src) in modules {
        std::fs::write(dir.join(format!("src/{name}.rs")), src).unwrap();
        let _ = writeln!(mods, "mod {name} {{ include!(\"{name}.rs\"); }}");
        let _ = writeln!(dispatch, "s.spawn(|| run::<{name}::Map>(dir, {name:?}));");
    }
    std::fs::write(
        dir.join("src/main.rs"),
        mods + &main.replace("DISPATCH", &dispatch),
    )
    .unwrap();
    let start = Instant::now();
    let build = Command::new(env!("CARGO"))
        .args(["build", "--release", "--offline", "--quiet"])
        .env("CARGO_TARGET_DIR", target_dir())
        .current_dir(dir)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&build.stderr);
    assert!(build.status.success(), "build failed:\n{stderr}");
    assert!(
        !stderr.contains("warning"),
        "generated code has warnings:\n{stderr}"
    );
    eprintln!(
        "built {} modules in {:.1} s",
        modules.len(),
        start.elapsed().as_secs_f64()
    );
    target_dir().join("release").join(crate_name)
}

fn close(a: f64, b: f64, rel: f64) -> bool {
    a == b || (a - b).abs() <= rel * b.abs().max(1.0)
}

/// The generated modules of one map (name and source of each variant) and the
/// evidence vectors they all run on.
pub type Prepared = (Vec<(String, String)>, Vec<Vec<Vec<f64>>>);

/// Writes the evidence file of every module (see [`MAIN`]), builds all modules into one
/// crate, runs it and returns, per map and module, its results (per vector see
/// [`stride`]).
pub fn run_modules(crate_name: &str, maps: &[Prepared]) -> Vec<Vec<Vec<f64>>> {
    let dir = tempfile::tempdir().unwrap();
    let mut all = vec![];
    for (modules, evs) in maps {
        let mut bytes = (evs.len() as u64).to_le_bytes().to_vec();
        for (v, e) in evs.iter().enumerate() {
            for x in e.iter().flatten() {
                bytes.extend_from_slice(&x.to_le_bytes());
            }
            for l in probe_labels(e, v) {
                let l = l.map_or(f64::from(u16::MAX), f64::from);
                bytes.extend_from_slice(&l.to_le_bytes());
            }
        }
        for (name, src) in modules {
            std::fs::write(dir.path().join(format!("{name}.ev")), &bytes).unwrap();
            all.push((name.clone(), src.clone()));
        }
    }
    let bin = build_crate(dir.path(), crate_name, &all);
    let run = Command::new(&bin).arg(dir.path()).output().unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let timing = String::from_utf8_lossy(&run.stdout).into_owned();
    eprint!(
        "generated code, seconds for all queries (ll + mpe + labelled ll + marginals):\n{timing}"
    );
    maps.iter()
        .map(|(modules, _)| {
            modules
                .iter()
                .map(|(name, _)| {
                    std::fs::read(dir.path().join(format!("{name}.out")))
                        .unwrap()
                        .chunks_exact(8)
                        .map(|b| f64::from_le_bytes(b.try_into().unwrap()))
                        .collect()
                })
                .collect()
        })
        .collect()
}

/// Generates, builds and runs every variant of every case, then checks them against
/// the interpreter (see [`check_case`]). Returns the generated modules (name, source).
pub fn differential(crate_name: &str, cases: &[Case]) -> Vec<(String, String)> {
    let prepared: Vec<Prepared> = cases
        .iter()
        .map(|case| {
            let modules = case
                .variants
                .iter()
                .map(|variant| {
                    let opts = CodegenOptions {
                        precision: variant.precision,
                        vectorisation: variant.vectorisation,
                        arithmetic: variant.arithmetic,
                        ..Default::default()
                    };
                    let name = case.module(variant);
                    let src = generate(&case.model, &case.map, &case.decs, &opts)
                        .unwrap_or_else(|e| panic!("{name}: {e}"));
                    (name, src)
                })
                .collect();
            (modules, case_evidence(case))
        })
        .collect();
    let results = run_modules(crate_name, &prepared);
    for ((case, (_, evs)), vals) in cases.iter().zip(&prepared).zip(&results) {
        let start = Instant::now();
        check_case(case, evs, vals);
        eprintln!(
            "{} ({} variants): {} places, {} vectors (seed {}) agree with the interpreter ({:.1} s)",
            case.name,
            case.variants.len(),
            case.map.num_places(),
            evs.len(),
            case.seed,
            start.elapsed().as_secs_f64()
        );
    }
    prepared.into_iter().flat_map(|(m, _)| m).collect()
}

/// The evidence vectors of a case, rounded through `f32` when some variant is `f32`
/// (so that every variant and the interpreter see the same numbers).
pub fn case_evidence(case: &Case) -> Vec<Vec<Vec<f64>>> {
    let (n, c) = (case.map.num_places(), case.model.classes.len());
    let round = case.variants.iter().any(|v| v.precision == Precision::F32);
    let mut rng = ChaCha8Rng::seed_from_u64(case.seed);
    (0..case.vectors)
        .map(|v| {
            let mut e = evidence(&mut rng, n, c, v);
            if round {
                for x in e.iter_mut().flatten() {
                    *x = *x as f32 as f64;
                }
            }
            e
        })
        .collect()
}

/// Evidence vectors the interpreter evaluates in one batched pass.
const LANES: usize = BATCH;

/// Every how many batches the labelled log-likelihood is checked (one more
/// sum-product pass of the interpreter).
const LABELLED_EVERY: usize = 4;

/// One generated module's answers to a case: module name, tolerance, results.
type Answers<'a> = (String, f64, &'a [f64]);

/// Compares the generated answers `vals` (one array per variant; per vector see
/// [`stride`]; NaN values on error) with the interpreter on the instance SPN, which
/// evaluates each vector once for all variants (batches of [`LANES`] vectors):
/// log-likelihood, marginals, MPE value, the value the generated MPE labels attain,
/// and (every [`LABELLED_EVERY`]th batch) the labelled log-likelihood of the
/// [`probe_labels`]. Tolerances per variant: see [`Variant`].
pub fn check_case(case: &Case, evs: &[Vec<Vec<f64>>], vals: &[Vec<f64>]) {
    let (n, c) = (case.map.num_places(), case.model.classes.len());
    let stride = stride(n, c);
    let answers: Vec<Answers> = case
        .variants
        .iter()
        .zip(vals)
        .map(|(var, v)| {
            let name = case.module(var);
            assert_eq!(v.len(), evs.len() * stride, "{name}: result size");
            (name, var.tolerance(), v.as_slice())
        })
        .collect();
    let inst = Instance::build(&case.model, &case.map, case.decs.clone()).unwrap();
    let eval = Evaluator::new(&inst.spn).unwrap();
    // One evaluator (a copy of the network's arrays) per thread, each taking one
    // contiguous share of the batches.
    let batches: Vec<&[Vec<Vec<f64>>]> = evs.chunks(LANES).collect();
    let share = batches.len().div_ceil(rayon::current_num_threads()).max(1);
    batches
        .par_chunks(share)
        .enumerate()
        .for_each(|(part, group)| {
            let mut ev = eval.clone();
            for (i, chunk) in group.iter().enumerate() {
                let b = part * share + i;
                let first = b * LANES;
                let labelled = b.is_multiple_of(LABELLED_EVERY);
                check_batch(case, &mut ev, &answers, first, chunk, labelled);
            }
        });
}

/// Checks vectors `first .. first + evs.len()` (at most [`LANES`]; a short last
/// batch is padded with copies of its first vector, whose results are not read).
fn check_batch(
    case: &Case,
    ev: &mut Evaluator,
    answers: &[Answers],
    first: usize,
    evs: &[Vec<Vec<f64>>],
    labelled: bool,
) {
    const K: usize = LANES;
    let used = evs.len();
    // The vector a lane evaluates (padding lanes repeat the first).
    let lane = |l: usize| if l < used { l } else { 0 };
    let (n, c) = (case.map.num_places(), case.model.classes.len());
    let stride = stride(n, c);
    let ctx = |module: &str, l: usize| {
        let v = first + l;
        format!(
            "module {module} seed {} vector {v} (kind {}): evidence {:?}",
            case.seed,
            v % 6,
            evs[l]
        )
    };
    let evidence: [Evidence; K] =
        std::array::from_fn(|l| Evidence::from_rows(evs[lane(l)].clone()));
    let evidence_refs: [&Evidence; K] = std::array::from_fn(|l| &evidence[l]);
    let free = vec![None; n];
    let frees: [&[Option<u32>]; K] = [free.as_slice(); K];
    // Where a lane's results are in a module's answers.
    let span = |l: usize| {
        let v = first + lane(l);
        v * stride..(v + 1) * stride
    };
    if labelled {
        let probes: [Vec<Option<u32>>; K] =
            std::array::from_fn(|l| probe_labels(&evs[lane(l)], first + lane(l)));
        let want =
            ev.log_likelihood_batch(std::array::from_fn(|l| probes[l].as_slice()), evidence_refs);
        for (name, tol, vals) in answers {
            for (l, want) in want.iter().enumerate().take(used) {
                let got = &vals[span(l)];
                match want {
                    Err(InferenceError::Evidence(EvidenceError::ZeroLikelihood)) => {
                        assert!(
                            got[2].is_nan(),
                            "labelled: zero likelihood: {}",
                            ctx(name, l)
                        );
                    }
                    Err(err) => panic!("interpreter: {err}: {}", ctx(name, l)),
                    Ok(w) => assert!(
                        close(got[2], *w, *tol),
                        "labelled log-likelihood {} vs {w}: {}",
                        got[2],
                        ctx(name, l)
                    ),
                }
            }
        }
    }
    let marginals = ev.marginals_batch(frees, evidence_refs);
    let best = ev.log_max_product_batch(frees, evidence_refs);
    for (name, tol, vals) in answers {
        let tol = *tol;
        let rows: [&[f64]; K] = std::array::from_fn(|l| &vals[span(l)]);
        // The value each lane's generated MPE labels attain.
        let labels: [Vec<Option<u32>>; K] =
            std::array::from_fn(|l| rows[l][3..3 + n].iter().map(|&x| Some(x as u32)).collect());
        let attained =
            ev.log_max_product_batch(std::array::from_fn(|l| labels[l].as_slice()), evidence_refs);
        for (l, got) in rows.iter().enumerate().take(used) {
            let m = match &marginals[l] {
                Err(InferenceError::Evidence(EvidenceError::ZeroLikelihood)) => {
                    assert!(
                        got[0].is_nan() && got[1].is_nan(),
                        "zero likelihood: {}",
                        ctx(name, l)
                    );
                    continue;
                }
                Err(err) => panic!("interpreter: {err}: {}", ctx(name, l)),
                Ok(m) => m,
            };
            assert!(
                close(got[0], m.log_likelihood, tol),
                "log-likelihood {} vs {}: {}",
                got[0],
                m.log_likelihood,
                ctx(name, l)
            );
            for p in 0..n {
                for k in 0..c {
                    let g = got[3 + n + p * c + k];
                    assert!(
                        (g - m.probs[p][k]).abs() <= tol,
                        "marginal place {p} class {k}: {g} vs {}: {}",
                        m.probs[p][k],
                        ctx(name, l)
                    );
                }
            }
            let best = *best[l].as_ref().unwrap();
            assert!(
                close(got[1], best, tol),
                "mpe value {} vs {best}: {}",
                got[1],
                ctx(name, l)
            );
            // The generated labels must attain that value.
            let attained = attained[l].as_ref().unwrap_or_else(|err| {
                panic!(
                    "generated mpe labels are impossible ({err}): {}",
                    ctx(name, l)
                )
            });
            assert!(
                close(*attained, best, tol),
                "generated mpe labels attain {attained} not {best}: {}",
                ctx(name, l)
            );
        }
    }
}
#[path = "../../compiler/tests/harness/temp_crate.rs"]
mod temp_crate;
pub mod trees;
