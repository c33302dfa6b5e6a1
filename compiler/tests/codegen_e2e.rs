//! End to end: generated modules are built into a temporary crate, run on evidence,
//! and compared with brute-force enumeration over all labellings (GraphSPN) or with
//! `TreeInstance`, the exact host evaluator (tree mixtures).

mod harness;

use std::fmt::Write as _;
use std::io::Write as _;
use std::path::PathBuf;
use std::process::{Command, Stdio};

use graphspn_compiler::codegen::{
    CodegenOptions, Precision, Vectorisation, generate, generate_trees_with_report,
};
use graphspn_compiler::decompose::Decomposition;
use graphspn_compiler::learn::Model;
use graphspn_compiler::map::{ClassId, TopoMap};
use graphspn_compiler::spn::Mixing;
use graphspn_compiler::template::Template;
use graphspn_compiler::treemix::{SpanningTrees, TreeInstance};
use harness::codegen::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

struct Case {
    name: String,
    model: Model,
    map: TopoMap,
    decs: Vec<Decomposition>,
    precision: Precision,
    /// Scalar code (microcontroller form) instead of SIMD lane groups.
    scalar: bool,
}

/// Evidence rows: random, exact zeros, tiny values, one-hot, uniform.
fn evidence(rng: &mut ChaCha8Rng, n: usize, c: usize, kind: usize) -> Vec<Vec<f64>> {
    (0..n)
        .map(|p| {
            (0..c)
                .map(|k| match (kind + p) % 5 {
                    0 => rng.random_range(0.01..1.0),
                    1 => {
                        if k == p % c {
                            rng.random_range(0.1..1.0)
                        } else {
                            0.0
                        }
                    }
                    2 => {
                        if k == 0 {
                            1e-30
                        } else {
                            rng.random_range(1e-30..1e-20)
                        }
                    }
                    3 => {
                        if rng.random_bool(0.5) {
                            0.0
                        } else {
                            rng.random_range(0.0..2.0) + 1e-3
                        }
                    }
                    _ => 0.5,
                })
                .collect::<Vec<f64>>()
        })
        .map(|mut row: Vec<f64>| {
            if row.iter().all(|&v| v == 0.0) {
                row[0] = 0.25;
            }
            row
        })
        .collect()
}

fn cases() -> Vec<Case> {
    let mut out = vec![];
    let (m, mp, decs) = tiny();
    for precision in [Precision::F32, Precision::F64] {
        out.push(Case {
            name: format!("tiny_{precision:?}"),
            model: m.clone(),
            map: mp.clone(),
            decs: decs.clone(),
            precision,
            scalar: false,
        });
    }
    for seed in 0..6u64 {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let c = 2 + (seed as usize % 2);
        let zeros = seed % 3 == 1;
        let scale = seed % 3 == 2;
        let templates = vec![Template::three(), Template::pair(), Template::singleton()];
        let spns = templates
            .iter()
            .map(|t| random_spn(&mut rng, t.num_nodes, c, zeros, scale))
            .collect();
        let m = model(c, templates, spns);
        let g = grid(3, 2, c);
        let decs: Vec<_> = (0..1 + seed % 3)
            .map(|s| decompose(&g, &m.templates, seed * 10 + s))
            .collect();
        let precision = if seed % 2 == 0 {
            Precision::F32
        } else {
            Precision::F64
        };
        out.push(Case {
            name: format!("rand{seed}"),
            model: m,
            map: g,
            decs,
            precision,
            scalar: seed % 2 == 1,
        });
    }
    // A Star on a 5-place plus-shaped map.
    let mut rng = ChaCha8Rng::seed_from_u64(99);
    let templates = vec![Template::star(), Template::pair(), Template::singleton()];
    let spns = templates
        .iter()
        .map(|t| random_spn(&mut rng, t.num_nodes, 2, false, false))
        .collect();
    let m = model(2, templates, spns);
    let g = map(6, 2, &[(0, 1), (0, 2), (0, 3), (0, 4), (4, 5)]);
    let decs: Vec<_> = (0..3).map(|s| decompose(&g, &m.templates, s)).collect();
    out.push(Case {
        name: "star".into(),
        model: m,
        map: g,
        decs,
        precision: Precision::F32,
        scalar: true,
    });
    // The real model structure (dense region blocks → the dense kernels): symmetric
    // Star/Three/Pair as trained by default, and plain dense ones with two random splits
    // per region (blocks with several segments of different shapes).
    for (name, symmetric, splits, precision, seed) in [
        ("dense_sym", true, 1, Precision::F32, 5u64),
        ("dense_sym64", true, 1, Precision::F64, 6),
        ("dense_split2", false, 2, Precision::F32, 7),
        ("dense_split3_64", false, 3, Precision::F64, 8),
    ] {
        let m = dense_model(3, symmetric, splits, seed);
        // A star around 0 with a tail: room for Star, Three, Pair and Singleton.
        let g = map(
            7,
            3,
            &[(0, 1), (0, 2), (0, 3), (0, 4), (4, 5), (5, 6), (1, 2)],
        );
        let decs: Vec<_> = (0..3)
            .map(|s| decompose(&g, &m.templates, seed + s))
            .collect();
        out.push(Case {
            name: name.into(),
            model: m,
            map: g,
            decs,
            precision,
            scalar: false,
        });
    }
    out
}

const MAIN: &str = r#"
use graphspn_runtime::CompiledMap;
use std::io::BufRead;

fn show<T: Into<f64>>(r: Result<T, graphspn_runtime::EvidenceError>) -> String {
    match r {
        Ok(v) => format!("{:e}", v.into()),
        Err(e) => format!("ERR:{e:?}").replace(' ', ""),
    }
}

fn run<M: CompiledMap>(toks: &[&str]) -> String
where
    M::Scalar: std::str::FromStr + Into<f64>,
{
    let (n, c) = (M::NUM_PLACES, M::NUM_CLASSES);
    let mut e = vec![M::ZERO_ROW; n];
    for p in 0..n {
        for k in 0..c {
            e[p].as_mut()[k] = toks[p * c + k].parse().ok().expect("number");
        }
    }
    let labels: Vec<u16> = toks[n * c..n * c + n].iter().map(|t| t.parse().expect("label")).collect();
    let mut out = vec![M::ZERO_ROW; n];
    let mut lab = vec![0u16; n];
    let mut s = String::new();
    s += &show(M::log_likelihood(&e));
    s += " ";
    s += &show(M::labelled_log_likelihood(&labels, &e));
    s += " ";
    s += &show(M::mpe(&e, &mut lab));
    for l in &lab {
        s += &format!(" {l}");
    }
    s += " ";
    s += &show(M::marginals(&e, &mut out));
    for row in &out {
        for v in row.as_ref() {
            s += &format!(" {:e}", (*v).into());
        }
    }
    s
}

fn main() {
    for line in std::io::stdin().lock().lines() {
        let line = line.unwrap();
        let toks: Vec<&str> = line.split_whitespace().collect();
        let r = match toks[0] {
            DISPATCH
            _ => panic!("unknown module"),
        };
        println!("{r}");
    }
}
"#;

fn target_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target/codegen-e2e")
}

/// Writes a crate named `name` holding every module, builds and runs it on `input`,
/// returns stdout. Tests run in parallel and share one target folder, so each test
/// names its own crate: with one name, a test could run the binary that another
/// test's build had just written.
pub fn build_and_run(name: &str, modules: &[(String, String)], input: &str) -> String {
    let dir = tempfile::tempdir().unwrap();
    let runtime = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../runtime")
        .canonicalize()
        .unwrap();
    std::fs::write(
        dir.path().join("Cargo.toml"),
        format!(
            "[package]\nname = \"{name}\"\nversion = \"0.0.0\"\nedition = \"2024\"\n\n[dependencies]\ngraphspn-runtime = {{ path = {:?} }}\n\n[workspace]\n",
            runtime.display().to_string()
        ),
    )
    .unwrap();
    harness::temp_crate::use_workspace_cargo_config(
        &PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(".."),
        dir.path(),
    );
    std::fs::create_dir_all(dir.path().join("src")).unwrap();
    let mut mods = String::new();
    let mut dispatch = String::new();
    for (name, src) in modules {
        std::fs::write(dir.path().join(format!("src/{name}.rs")), src).unwrap();
        let _ = writeln!(mods, "mod {name} {{ include!(\"{name}.rs\"); }}");
        let _ = writeln!(dispatch, "{name:?} => run::<{name}::Map>(&toks[1..]),");
    }
    let main = mods + &MAIN.replace("DISPATCH", &dispatch);
    std::fs::write(dir.path().join("src/main.rs"), main).unwrap();
    let build = Command::new(env!("CARGO"))
        .args(["build", "--release", "--offline", "--quiet"])
        .env("CARGO_TARGET_DIR", target_dir())
        .current_dir(dir.path())
        .output()
        .unwrap();
    assert!(
        build.status.success(),
        "build failed:\n{}",
        String::from_utf8_lossy(&build.stderr)
    );
    let warnings = String::from_utf8_lossy(&build.stderr);
    assert!(
        !warnings.contains("warning"),
        "generated code has warnings:\n{warnings}"
    );
    let mut child = Command::new(target_dir().join("release").join(name))
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    child
        .stdin
        .take()
        .unwrap()
        .write_all(input.as_bytes())
        .unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success());
    String::from_utf8(out.stdout).unwrap()
}

fn close(a: f64, b: f64, rel: f64) -> bool {
    if a == b {
        return true;
    }
    (a - b).abs() <= rel * a.abs().max(b.abs()).max(1.0)
}

#[test]
fn generated_code_matches_brute_force() {
    let cases = cases();
    let mut modules = vec![];
    let mut input = String::new();
    let mut expected = vec![];
    let mut rng = ChaCha8Rng::seed_from_u64(2024);
    for case in &cases {
        let opts = CodegenOptions {
            precision: case.precision,
            vectorisation: if case.scalar {
                Vectorisation::Scalar
            } else {
                Vectorisation::Simd
            },
            ..Default::default()
        };
        let src = generate(&case.model, &case.map, &case.decs, &opts).unwrap();
        modules.push((case.name.to_lowercase(), src));
        let n = case.map.num_places();
        let c = case.map.classes.len();
        for kind in 0..6 {
            let e = evidence(&mut rng, n, c, kind);
            let labels: Vec<u16> = (0..n)
                .map(|p| {
                    if (p + kind) % 3 == 0 {
                        u16::MAX
                    } else {
                        ((p * 7 + kind) % c) as u16
                    }
                })
                .collect();
            // Round evidence through the scalar type so the oracle sees what the code sees.
            let e: Vec<Vec<f64>> = e
                .iter()
                .map(|r| {
                    r.iter()
                        .map(|&v| {
                            if case.precision == Precision::F32 {
                                v as f32 as f64
                            } else {
                                v
                            }
                        })
                        .collect()
                })
                .collect();
            let _ = write!(input, "{}", case.name.to_lowercase());
            for r in &e {
                for v in r {
                    let _ = write!(input, " {v:e}");
                }
            }
            for l in &labels {
                let _ = write!(input, " {l}");
            }
            input.push('\n');
            expected.push((
                case,
                e.clone(),
                labels.clone(),
                oracle(&case.model, &case.decs, &e, &labels),
            ));
        }
    }
    let out = build_and_run("e2e-brute-force", &modules, &input);
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(lines.len(), expected.len());
    let mut zero_cases = 0;
    for (line, (case, e, labels, o)) in lines.iter().zip(&expected) {
        let ctx = format!(
            "case {} evidence {e:?} labels {labels:?}\noracle {o:?}\ngot {line}",
            case.name
        );
        let n = e.len();
        let (tol_ll, tol_m) = match case.precision {
            Precision::F32 => (1e-4, 1e-4),
            Precision::F64 => (1e-9, 1e-9),
        };
        let t: Vec<&str> = line.split_whitespace().collect();
        let num = |s: &str| {
            s.parse::<f64>()
                .unwrap_or_else(|_| panic!("not a number {s}\n{ctx}"))
        };
        if o.ll == f64::NEG_INFINITY {
            // Zero weights exclude everything the evidence allows: every query must say so.
            zero_cases += 1;
            assert_eq!(t[0], "ERR:ZeroLikelihood", "{ctx}");
            assert_eq!(t[1], "ERR:ZeroLikelihood", "{ctx}");
            assert_eq!(t[3 + n], "ERR:ZeroLikelihood", "{ctx}");
            continue;
        }
        assert!(close(num(t[0]), o.ll, tol_ll), "log-likelihood\n{ctx}");
        if o.lll == f64::NEG_INFINITY {
            assert_eq!(t[1], "ERR:ZeroLikelihood", "labelled\n{ctx}");
        } else {
            assert!(
                close(num(t[1]), o.lll, tol_ll),
                "labelled log-likelihood\n{ctx}"
            );
        }
        assert!(close(num(t[2]), o.mpe, tol_ll), "mpe value\n{ctx}");
        // The returned labelling attains the max-product value.
        let lab: Vec<usize> = t[3..3 + n].iter().map(|s| s.parse().unwrap()).collect();
        let masked: Vec<Vec<f64>> = e
            .iter()
            .zip(&lab)
            .map(|(r, &l)| {
                r.iter()
                    .enumerate()
                    .map(|(k, &v)| if k == l { v } else { 0.0 })
                    .collect()
            })
            .collect();
        let attained = max_product(&case.model, &case.decs, &masked).ln();
        assert!(
            close(attained, o.mpe, tol_ll * 10.0),
            "mpe labels attain {attained}\n{ctx}"
        );
        assert!(
            close(num(t[3 + n]), o.ll, tol_ll),
            "marginals' log-likelihood\n{ctx}"
        );
        let marg: Vec<f64> = t[4 + n..].iter().map(|s| num(s)).collect();
        for (p, row) in o.marg.iter().enumerate() {
            for (k, &v) in row.iter().enumerate() {
                let g = marg[p * row.len() + k];
                assert!(
                    (g - v).abs() <= tol_m,
                    "marginal p{p} c{k}: {g} vs {v}\n{ctx}"
                );
            }
        }
    }
    assert!(zero_cases < expected.len() / 4, "too few informative cases");
}

/// What `TreeInstance` answers for one evidence vector.
struct TreeExpected {
    module: String,
    /// Index of the module's instance.
    instance: usize,
    evidence: Vec<Vec<f64>>,
    precision: Precision,
    labels: Vec<u16>,
    ll: f64,
    /// `None` where the labelling has zero likelihood.
    labelled: Option<f64>,
    mpe: f64,
    marginals: Vec<Vec<f64>>,
}

/// Generated tree-mixture modules (f32 / f64, scalar / SIMD) on random maps of 2 to 8
/// places with 1 to 3 forests and evidence exponents 1 and 2, against `TreeInstance`:
/// log-likelihood, labelled log-likelihood, the MPE value and the value its labelling
/// attains, and the marginals. (The root crate's `tree_fuzz` goes further; this keeps
/// the generator's own tests running its tree code.)
#[test]
fn generated_tree_code_matches_the_tree_instance() {
    use harness::instance::tiny_map;
    use harness::treemix::random_model;
    let mut modules = vec![];
    let mut input = String::new();
    let mut expected = vec![];
    let mut instances = vec![];
    let mut rng = ChaCha8Rng::seed_from_u64(77);
    for seed in 0..8u64 {
        let s = seed as usize;
        let (n, c, t) = (2 + s % 7, 2 + s % 3, 1 + s % 3);
        let map = tiny_map(n, c, seed);
        let model = random_model(c, t, 1 + (s % 2) as u32, Mixing::Posterior, seed);
        let trees = SpanningTrees::covering(&map, t, seed).unwrap();
        let precision = [Precision::F32, Precision::F64][s % 2];
        let options = CodegenOptions {
            precision,
            vectorisation: [Vectorisation::Scalar, Vectorisation::Simd][s / 2 % 2],
            ..Default::default()
        };
        let (src, _) = generate_trees_with_report(&model, &map, &trees, &options).unwrap();
        let module = format!("trees{seed}");
        modules.push((module.clone(), src));
        let mut inst = TreeInstance::build(&model, &map, trees).unwrap();
        for kind in [0, 1, 3, 4, 5] {
            let e: Vec<Vec<f64>> = evidence(&mut rng, n, c, kind)
                .into_iter()
                .map(|r| match precision {
                    Precision::F32 => r.into_iter().map(|v| v as f32 as f64).collect(),
                    Precision::F64 => r,
                })
                .collect();
            let labels: Vec<u16> = (0..n)
                .map(|p| match (p + kind) % 3 {
                    0 => u16::MAX,
                    _ => ((p * 7 + kind) % c) as u16,
                })
                .collect();
            let fixed: Vec<Option<ClassId>> = labels
                .iter()
                .map(|&l| (l != u16::MAX).then_some(l))
                .collect();
            inst.set_all_evidence(&e).unwrap();
            let _ = write!(input, "{module}");
            for v in e.iter().flatten() {
                let _ = write!(input, " {v:e}");
            }
            for l in &labels {
                let _ = write!(input, " {l}");
            }
            input.push('\n');
            expected.push(TreeExpected {
                module: module.clone(),
                instance: instances.len(),
                evidence: e.clone(),
                precision,
                labels,
                ll: inst.log_likelihood().unwrap(),
                labelled: inst
                    .log_likelihood_labelled(&fixed)
                    .ok()
                    .filter(|l| l.is_finite()),
                mpe: inst.mpe(&vec![None; n]).unwrap().log_max_product,
                marginals: inst.marginals().unwrap().mixed.probs,
            });
        }
        instances.push(inst);
    }
    let out = build_and_run("e2e-trees", &modules, &input);
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(lines.len(), expected.len());
    for (line, x) in lines.iter().zip(&expected) {
        let ctx = format!("{} labels {:?}\ngot {line}", x.module, x.labels);
        let (n, tol) = match x.precision {
            Precision::F32 => (x.labels.len(), 1e-4),
            Precision::F64 => (x.labels.len(), 1e-9),
        };
        let t: Vec<&str> = line.split_whitespace().collect();
        let num = |s: &str| {
            s.parse::<f64>()
                .unwrap_or_else(|_| panic!("not a number {s}\n{ctx}"))
        };
        assert!(
            close(num(t[0]), x.ll, tol),
            "log-likelihood {}\n{ctx}",
            x.ll
        );
        match x.labelled {
            Some(l) => assert!(close(num(t[1]), l, tol), "labelled {l}\n{ctx}"),
            None => assert_eq!(t[1], "ERR:ZeroLikelihood", "labelled\n{ctx}"),
        }
        assert!(close(num(t[2]), x.mpe, tol), "mpe value {}\n{ctx}", x.mpe);
        // The returned labelling attains the max-product value.
        let inst = &mut instances[x.instance];
        inst.set_all_evidence(&x.evidence).unwrap();
        let lab: Vec<Option<ClassId>> = t[3..3 + n].iter().map(|s| s.parse().ok()).collect();
        let attained = inst.mpe(&lab).unwrap().log_max_product;
        assert!(
            close(attained, x.mpe, tol),
            "mpe labels attain {attained}\n{ctx}"
        );
        assert!(
            close(num(t[3 + n]), x.ll, tol),
            "marginals' log-likelihood\n{ctx}"
        );
        let marg: Vec<f64> = t[4 + n..].iter().map(|s| num(s)).collect();
        for (p, row) in x.marginals.iter().enumerate() {
            for (k, &v) in row.iter().enumerate() {
                let g = marg[p * row.len() + k];
                assert!(
                    (g - v).abs() <= tol,
                    "marginal p{p} c{k}: {g} vs {v}\n{ctx}"
                );
            }
        }
    }
}
