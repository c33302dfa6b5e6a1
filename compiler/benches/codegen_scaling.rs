//! Code size, release build time and run time of generated code as maps grow, and the
//! speed-up over the interpreter on the largest COLD map.
//!
//! Model: `$GRAPHSPN_MODEL`, else the demo model the `generated` crate ships
//! (`generated/demo/model.json`, trained on all COLD maps). Maps: synthetic office floors
//! (`map::synthetic`) of about 100, 1,000 and 10,000 places (`CODEGEN_SIZES` to
//! choose), plus Saarbrucken's largest COLD map (shipped copy, or `$GRAPHSPN_DATA`); each with 5
//! decompositions from the real decomposer (`decompose_best`, 15 candidates).
//! For every map a crate holding just the generated module is built in release mode
//! (`target/codegen-bench`, the runtime prebuilt so the time is the module's own; the
//! workspace's `.cargo/config.toml`, i.e. its target CPU, is copied in) and run; the interpreter's marginals on the same instance SPN and evidence are timed in
//! this process. Machine code: bytes of the built binary's functions that belong to
//! the generated module or to the runtime driver it instantiates (`nm -S`, text
//! symbols), and of the module's tables (read-only data symbols).
//! `CODEGEN_NO_BUILD=1` only generates; `CODEGEN_KEEP=1` keeps the sources.
//!
//! Run: `cargo bench -p graphspn-compiler --bench codegen_scaling`.

use std::path::PathBuf;
use std::process::Command;
use std::time::Instant;

use graphspn_compiler::codegen::{CodegenOptions, generate};
use graphspn_compiler::decompose::{DecompositionParams, decompose_best};
use graphspn_compiler::instance::Instance;
use graphspn_compiler::interpreter::{Evaluator, Evidence};
use graphspn_compiler::learn::Model;
use graphspn_compiler::map::TopoMap;
use graphspn_compiler::map::synthetic::{SyntheticParams, generate as synth};

const MAIN: &str = r#"
#[allow(dead_code)]
mod m { include!("m.rs"); }
fn main() {
    let mut e = Box::new([[0.0f32; m::NUM_CLASSES]; m::NUM_PLACES]);
    let mut s = 12345u64;
    for row in e.iter_mut() {
        for v in row.iter_mut() {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            *v = ((s >> 40) as f32 / (1u64 << 24) as f32) + 1e-3;
        }
    }
    let mut out = Box::new([[0.0f32; m::NUM_CLASSES]; m::NUM_PLACES]);
    let mut lab = Box::new([0u16; m::NUM_PLACES]);
    let iters = (2_000_000 / m::NUM_PLACES).max(5);
    let t = std::time::Instant::now();
    let mut acc = 0.0f32;
    for _ in 0..iters { acc += m::log_likelihood(std::hint::black_box(&e)).unwrap(); }
    let ll = t.elapsed().as_secs_f64() / iters as f64;
    let t = std::time::Instant::now();
    for _ in 0..iters { acc += m::marginals(std::hint::black_box(&e), &mut out).unwrap(); }
    let mg = t.elapsed().as_secs_f64() / iters as f64;
    let t = std::time::Instant::now();
    for _ in 0..iters { acc += m::mpe(std::hint::black_box(&e), &mut lab).unwrap(); }
    let mp = t.elapsed().as_secs_f64() / iters as f64;
    println!("{:.1} {:.1} {:.1} {} {:e}", ll * 1e6, mg * 1e6, mp * 1e6, acc, out[0][0]);
}
"#;

/// The evidence `MAIN` builds, in `f64`.
fn evidence(n: usize, c: usize) -> Vec<Vec<f64>> {
    let mut s = 12345u64;
    (0..n)
        .map(|_| {
            (0..c)
                .map(|_| {
                    s = s
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    f64::from(((s >> 40) as f32 / (1u64 << 24) as f32) + 1e-3)
                })
                .collect()
        })
        .collect()
}

fn load_model() -> (Model, String) {
    let path = std::env::var("GRAPHSPN_MODEL").unwrap_or_else(|_| {
        concat!(env!("CARGO_MANIFEST_DIR"), "/../generated/demo/model.json").into()
    });
    let model = Model::load(&path).unwrap_or_else(|e| panic!("model {path}: {e}"));
    (model, path)
}

fn maps(model: &Model) -> Vec<(String, TopoMap)> {
    let sizes: Vec<usize> = std::env::var("CODEGEN_SIZES")
        .unwrap_or_else(|_| "100,1000,10000".into())
        .split(',')
        .filter_map(|s| s.trim().parse().ok())
        .collect();
    let mut out = vec![];
    {
        let data = graphspn_compiler::map::cold::data_dir(None);
        let maps = graphspn_compiler::map::cold::load_building(&data, "Saarbrucken")
            .expect("the COLD data folder holds Saarbrucken");
        let big = maps
            .into_iter()
            .max_by_key(|m| m.num_places())
            .expect("Saarbrucken has maps");
        out.push((format!("cold:{}", big.name), big));
    }
    for n in sizes {
        let mut map = synth(&SyntheticParams::new(n, 1)).expect("synthetic map");
        map.classes = model.classes.clone();
        out.push((format!("synthetic {n}"), map));
    }
    out
}

fn main() {
    let (model, label) = load_model();
    println!("model: {label}");
    let target = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target/codegen-bench");
    let runtime = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../runtime")
        .canonicalize()
        .expect("runtime folder");
    println!(
        "map | places | unique comps | gen ms | source KB | build s | code KB | tables KB | ll µs | marginals µs | mpe µs | interp marginals µs | speed-up"
    );
    for (name, map) in maps(&model) {
        let decs = decompose_best(
            &map,
            &model.templates,
            &DecompositionParams {
                count: 5,
                candidates: 15,
                seed: 1,
                ..DecompositionParams::default()
            },
        )
        .expect("decompose");
        let mut uniq: Vec<_> = decs.iter().flat_map(|d| d.components.iter()).collect();
        uniq.sort_by(|a, b| (a.template, &a.places).cmp(&(b.template, &b.places)));
        uniq.dedup_by(|a, b| a.template == b.template && a.places == b.places);
        let t = Instant::now();
        let opts = CodegenOptions {
            model_label: label.clone(),
            ..Default::default()
        };
        let src = generate(&model, &map, &decs, &opts).expect("generate");
        let gen_ms = t.elapsed().as_secs_f64() * 1e3;
        let n = map.num_places();
        // The interpreter on the same instance and evidence (in-process).
        let interp_us = if n <= 2000 {
            let inst = Instance::build(&model, &map, decs.clone()).expect("instance");
            let mut ev = Evaluator::new(&inst.spn).expect("evaluator");
            let e = Evidence::from_rows(evidence(n, model.classes.len()));
            let fixed = vec![None; n];
            let _ = ev.marginals(&fixed, &e).expect("interpreter");
            let iters = 5;
            let t = Instant::now();
            for _ in 0..iters {
                std::hint::black_box(ev.marginals(&fixed, &e).expect("interpreter"));
            }
            Some(t.elapsed().as_secs_f64() / iters as f64 * 1e6)
        } else {
            None
        };
        if std::env::var_os("CODEGEN_KEEP").is_some() {
            let _ = std::fs::create_dir_all(&target);
            let _ = std::fs::write(target.join(format!("m_{n}.rs")), &src);
        }
        let row = format!(
            "{name} | {n} | {} | {gen_ms:.0} | {}",
            uniq.len(),
            src.len() / 1024
        );
        let interp = interp_us.map_or("-".to_string(), |v| format!("{v:.0}"));
        if std::env::var_os("CODEGEN_NO_BUILD").is_some() {
            println!("{row} | - | - | - | - | - | - | {interp} | -");
            continue;
        }
        let dir = tempfile::tempdir().expect("tempdir");
        std::fs::write(
            dir.path().join("Cargo.toml"),
            format!(
                "[package]\nname = \"codegen-bench\"\nversion = \"0.0.0\"\nedition = \"2024\"\n\n[dependencies]\ngraphspn-runtime = {{ path = {:?} }}\n\n[workspace]\n",
                runtime.display().to_string()
            ),
        )
        .expect("write");
        std::fs::create_dir_all(dir.path().join("src")).expect("mkdir");
        // Same code generation flags as this workspace (target CPU).
        let config = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../.cargo/config.toml");
        if let Ok(text) = std::fs::read_to_string(&config) {
            std::fs::create_dir_all(dir.path().join(".cargo")).expect("mkdir");
            std::fs::write(dir.path().join(".cargo/config.toml"), text).expect("write");
        }
        std::fs::write(dir.path().join("src/m.rs"), &src).expect("write");
        std::fs::write(dir.path().join("src/main.rs"), MAIN).expect("write");
        // Build the runtime first so the timing is the generated crate's alone.
        let _ = Command::new(env!("CARGO"))
            .args([
                "build",
                "--release",
                "--offline",
                "--quiet",
                "-p",
                "graphspn-runtime",
            ])
            .env("CARGO_TARGET_DIR", &target)
            .current_dir(dir.path())
            .status();
        let t = Instant::now();
        let st = Command::new(env!("CARGO"))
            .args(["build", "--release", "--offline", "--quiet"])
            .env("CARGO_TARGET_DIR", &target)
            .current_dir(dir.path())
            .status()
            .expect("cargo");
        let build_s = t.elapsed().as_secs_f64();
        assert!(st.success(), "generated crate failed to build");
        let (code, tables) = machine_code(&target.join("release/codegen-bench"));
        let out = Command::new(target.join("release/codegen-bench"))
            .output()
            .expect("run");
        let times = String::from_utf8_lossy(&out.stdout).to_string();
        let t: Vec<&str> = times.split_whitespace().collect();
        let mg: Option<f64> = t.get(1).and_then(|s| s.parse().ok());
        let ratio = match (interp_us, mg) {
            (Some(i), Some(g)) if g > 0.0 => format!("{:.0}×", i / g),
            _ => "-".into(),
        };
        println!(
            "{row} | {build_s:.1} | {} | {} | {} | {} | {} | {interp} | {ratio}",
            code / 1024,
            tables / 1024,
            t.first().unwrap_or(&"?"),
            t.get(1).unwrap_or(&"?"),
            t.get(2).unwrap_or(&"?")
        );
    }
}

/// Bytes of machine code (text symbols of the generated module `m` and of the
/// runtime it instantiates) and of the module's read-only tables in binary `bin`,
/// from `nm -S`; `(0, 0)` if `nm` is missing.
fn machine_code(bin: &std::path::Path) -> (usize, usize) {
    let Ok(out) = Command::new("nm")
        .args(["-S", "-C", "-t", "d"])
        .arg(bin)
        .output()
    else {
        return (0, 0);
    };
    let (mut code, mut tables) = (0, 0);
    for line in String::from_utf8_lossy(&out.stdout).lines() {
        let f: Vec<&str> = line.splitn(4, ' ').collect();
        let [_, size, kind, name] = f[..] else {
            continue;
        };
        let size: usize = size.parse().unwrap_or(0);
        let module = name.starts_with("codegen_bench::m::");
        match kind {
            "t" | "T" if module || name.starts_with("graphspn_runtime::") => code += size,
            "r" | "R" | "d" | "D" if module => tables += size,
            _ => {}
        }
    }
    (code, tables)
}
