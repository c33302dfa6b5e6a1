//! Shared harness of the cross-crate tests: builds generated modules into ONE
//! temporary crate (one module per map, so rustc runs once), runs its binary on
//! evidence files, and compares every answer with the interpreter evaluating the
//! instance GraphSPN.
#![allow(dead_code)]

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use graphspn::codegen::{CodegenOptions, Precision, generate};
use graphspn::decompose::Decomposition;
use graphspn::instance::Instance;
use graphspn::interpreter::{Evaluator, Evidence, InferenceError};
use graphspn::learn::Model;
use graphspn::map::TopoMap;
use graphspn_runtime::EvidenceError;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

/// One map to compile and test.
pub struct Case {
    /// Module name (a Rust identifier).
    pub name: String,
    /// The model.
    pub model: Model,
    /// The map.
    pub map: TopoMap,
    /// The decompositions.
    pub decs: Vec<Decomposition>,
    /// Scalar type of the generated code.
    pub precision: Precision,
    /// Number of random evidence vectors.
    pub vectors: usize,
    /// Seed of the evidence.
    pub seed: u64,
    /// Stack budget of the generated marginals (`0`: always the two-pass form).
    pub max_stack_bytes: usize,
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

/// The temporary crate's main: for every module, reads `<name>.ev` (u64 count, then
/// count × n × c little-endian f64), writes `<name>.out`: per vector `ll`, `mpe value`
/// (NaN on error), n labels as f64, n × c marginals; prints the query time.
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
    assert_eq!(vals.len(), count * n * c);
    let mut evs = vec![vec![M::ZERO_ROW; n]; count];
    for (v, ev) in evs.iter_mut().enumerate() {
        for p in 0..n {
            for k in 0..c {
                ev[p].as_mut()[k] = M::Scalar::from_f64(vals[(v * n + p) * c + k]);
            }
        }
    }
    let mut out = Vec::with_capacity(count * (2 + n + n * c) * 8);
    let mut marg = vec![M::ZERO_ROW; n];
    let mut lab = vec![0u16; n];
    let start = std::time::Instant::now();
    for ev in &evs {
        let ll = M::log_likelihood(ev).map_or(f64::NAN, Into::into);
        let mv = M::mpe(ev, &mut lab).map_or(f64::NAN, Into::into);
        let _ = M::marginals(ev, &mut marg);
        out.extend_from_slice(&ll.to_le_bytes());
        out.extend_from_slice(&mv.to_le_bytes());
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
    std::fs::write(dir.join(format!("{name}.out")), out).expect("write results");
    let _ = writeln!(std::io::stdout(), "{name} {count} {secs}");
}

trait FromF64 { fn from_f64(x: f64) -> Self; }
impl FromF64 for f32 { fn from_f64(x: f64) -> Self { x as f32 } }
impl FromF64 for f64 { fn from_f64(x: f64) -> Self { x } }

fn main() {
    let dir = std::path::PathBuf::from(std::env::args().nth(1).expect("data folder"));
    DISPATCH
}
"#;

/// Shared target folder of the temporary crates (keeps the runtime's build cached).
fn target_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target/generated-tests")
}

/// Writes a crate holding every module, builds it in release and returns the binary.
/// Panics with rustc's messages if the build fails or warns.
pub fn build_crate(dir: &Path, crate_name: &str, modules: &[(String, String)]) -> PathBuf {
    let runtime = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("runtime");
    std::fs::write(
        dir.join("Cargo.toml"),
        format!(
            "[package]\nname = \"{crate_name}\"\nversion = \"0.0.0\"\nedition = \"2024\"\n\n[dependencies]\ngraphspn-runtime = {{ path = {:?} }}\n\n[workspace]\n",
            runtime.display().to_string()
        ),
    )
    .unwrap();
    std::fs::create_dir_all(dir.join("src")).unwrap();
    let mut mods = String::new();
    let mut dispatch = String::new();
    for (name, src) in modules {
        std::fs::write(dir.join(format!("src/{name}.rs")), src).unwrap();
        let _ = writeln!(mods, "mod {name} {{ include!(\"{name}.rs\"); }}");
        let _ = writeln!(dispatch, "run::<{name}::Map>(&dir, {name:?});");
    }
    std::fs::write(
        dir.join("src/main.rs"),
        mods + &MAIN.replace("DISPATCH", &dispatch),
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

/// Generates, builds and runs every case, then checks it against the interpreter:
/// log-likelihood (relative 1e-4 in f32, 1e-9 in f64), marginals (absolute, same),
/// MPE value (same relative bound) and the value of the generated MPE labels.
pub fn differential(crate_name: &str, cases: &[Case]) {
    let dir = tempfile::tempdir().unwrap();
    let mut modules = vec![];
    let mut inputs = vec![];
    for case in cases {
        let opts = CodegenOptions {
            precision: case.precision,
            max_stack_bytes: case.max_stack_bytes,
            ..Default::default()
        };
        let src = generate(&case.model, &case.map, &case.decs, &opts)
            .unwrap_or_else(|e| panic!("{}: {e}", case.name));
        modules.push((case.name.clone(), src));
        let evs = case_evidence(case);
        let mut bytes = (case.vectors as u64).to_le_bytes().to_vec();
        for e in &evs {
            for r in e {
                for x in r {
                    bytes.extend_from_slice(&x.to_le_bytes());
                }
            }
        }
        std::fs::write(dir.path().join(format!("{}.ev", case.name)), bytes).unwrap();
        inputs.push(evs);
    }
    let bin = build_crate(dir.path(), crate_name, &modules);
    let run = Command::new(&bin).arg(dir.path()).output().unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let timing = String::from_utf8_lossy(&run.stdout).into_owned();
    eprint!("generated code, seconds for all queries (ll + mpe + marginals):\n{timing}");
    for (case, evs) in cases.iter().zip(&inputs) {
        let start = Instant::now();
        let bytes = std::fs::read(dir.path().join(format!("{}.out", case.name))).unwrap();
        let vals: Vec<f64> = bytes
            .chunks_exact(8)
            .map(|b| f64::from_le_bytes(b.try_into().unwrap()))
            .collect();
        check_case(case, evs, &vals);
        eprintln!(
            "{}: {} places, {} vectors (seed {}) agree with the interpreter ({:.1} s)",
            case.name,
            case.map.num_places(),
            evs.len(),
            case.seed,
            start.elapsed().as_secs_f64()
        );
    }
}

/// The evidence vectors of a case (rounded through `f32` for `f32` code).
pub fn case_evidence(case: &Case) -> Vec<Vec<Vec<f64>>> {
    let (n, c) = (case.map.num_places(), case.model.classes.len());
    let mut rng = ChaCha8Rng::seed_from_u64(case.seed);
    (0..case.vectors)
        .map(|v| {
            let mut e = evidence(&mut rng, n, c, v);
            if case.precision == Precision::F32 {
                for r in e.iter_mut() {
                    for x in r.iter_mut() {
                        *x = *x as f32 as f64;
                    }
                }
            }
            e
        })
        .collect()
}

/// Compares generated answers `vals` (per vector: ll, mpe value, n labels, n × c
/// marginals; NaN values on error) with the interpreter on the instance SPN.
pub fn check_case(case: &Case, evs: &[Vec<Vec<f64>>], vals: &[f64]) {
    let (n, c) = (case.map.num_places(), case.model.classes.len());
    let stride = 2 + n + n * c;
    assert_eq!(vals.len(), evs.len() * stride, "{}: result size", case.name);
    let inst = Instance::build(&case.model, &case.map, case.decs.clone()).unwrap();
    let eval = Evaluator::new(&inst.spn).unwrap();
    let tol = match case.precision {
        Precision::F32 => 1e-4,
        Precision::F64 => 1e-9,
    };
    let free = vec![None; n];
    evs.par_iter().enumerate().for_each_init(
        || eval.clone(),
        |ev, (v, e)| {
            let got = &vals[v * stride..(v + 1) * stride];
            let ctx = || {
                format!(
                    "map {} seed {} vector {v} (kind {}): evidence {e:?}",
                    case.name,
                    case.seed,
                    v % 6
                )
            };
            let evidence = Evidence::from_rows(e.clone());
            match ev.marginals(&free, &evidence) {
                Err(InferenceError::Evidence(EvidenceError::ZeroLikelihood)) => {
                    assert!(
                        got[0].is_nan() && got[1].is_nan(),
                        "zero likelihood: {}",
                        ctx()
                    );
                }
                Err(err) => panic!("interpreter: {err}: {}", ctx()),
                Ok(m) => {
                    assert!(
                        close(got[0], m.log_likelihood, tol),
                        "log-likelihood {} vs {}: {}",
                        got[0],
                        m.log_likelihood,
                        ctx()
                    );
                    for p in 0..n {
                        for k in 0..c {
                            let g = got[2 + n + p * c + k];
                            assert!(
                                (g - m.probs[p][k]).abs() <= tol,
                                "marginal place {p} class {k}: {g} vs {}: {}",
                                m.probs[p][k],
                                ctx()
                            );
                        }
                    }
                    let mpe = ev.mpe(&free, &evidence).unwrap();
                    assert!(
                        close(got[1], mpe.log_max_product, tol),
                        "mpe value {} vs {}: {}",
                        got[1],
                        mpe.log_max_product,
                        ctx()
                    );
                    // That the generated labels attain the max-product value is an
                    // extra check (one more interpreter pass): every 10th vector.
                    if v % 10 != 0 {
                        return;
                    }
                    let labels: Vec<Option<u32>> =
                        got[2..2 + n].iter().map(|&l| Some(l as u32)).collect();
                    let attained = ev.mpe(&labels, &evidence).unwrap_or_else(|err| {
                        panic!("generated mpe labels are impossible ({err}): {}", ctx())
                    });
                    assert!(
                        close(attained.log_max_product, mpe.log_max_product, tol),
                        "generated mpe labels attain {} not {}: {}",
                        attained.log_max_product,
                        mpe.log_max_product,
                        ctx()
                    );
                }
            }
        },
    );
}
