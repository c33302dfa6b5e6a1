//! How often the fixed-point kernel of targets without an FPU hands a template call to
//! its `f32` functions, on evidence simulated as in the paper's protocol. A fallback
//! costs about ten times its fixed-point twin, so this rate decides what a call costs
//! on a Cortex-M3 or RV32IMAC with real evidence (the firmware's own evidence,
//! independent uniform rows, rarely falls back).
//!
//! `cargo bench --bench fixed_fallbacks` builds the demo model's fixed-point module of
//! the 230-place map (seed 0, 5 decompositions) for the host with the runtime's
//! `fallback-counts` feature (the integer arithmetic, thresholds and so the counts are
//! those of the microcontroller build), runs it on `GRAPHSPN_FALLBACK_VECTORS` (20)
//! evidence vectors per noise level NL1–NL6, with every place observed and with the
//! placeholders unobserved, and prints the percentage of template calls answered by
//! `f32`: the value calls of `log_likelihood`, the value and posterior calls of a
//! stateless `marginals`, and the posterior calls of a streaming state that observes
//! every place of a vector in turn. Evidence seeds: `derive_seed(0, [level, vector])`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

use graphspn_compiler::codegen::{Arithmetic, Builder, Vectorisation};
use graphspn_compiler::noise::{NoiseLevel, derive_seed, simulate_map_evidence};

/// The temporary crate's `main`: reads the evidence file (`u64` vector count, then per
/// vector `N·C` `f32` entries, group after group) and prints one line of counts per
/// group (see [`Counts`]).
const MAIN: &str = r#"
use graphspn_runtime::{CompiledMap, fallback_counts, reset_fallback_counts};

mod map { include!("map.rs"); }
type M = map::Map;

fn main() {
    let path = std::env::args().nth(1).expect("evidence file");
    let per_group: usize = std::env::args().nth(2).expect("vectors per group").parse().unwrap();
    let bytes = std::fs::read(path).expect("evidence file");
    let (n, c) = (M::NUM_PLACES, M::NUM_CLASSES);
    let vals: Vec<f32> = bytes.chunks_exact(4).map(|b| f32::from_le_bytes(b.try_into().unwrap())).collect();
    let vectors: Vec<Vec<[f32; map::NUM_CLASSES]>> = vals
        .chunks_exact(n * c)
        .map(|v| v.chunks_exact(c).map(|r| r.try_into().unwrap()).collect())
        .collect();
    let mut marg = vec![[0f32; map::NUM_CLASSES]; n];
    for group in vectors.chunks(per_group) {
        let mut line = Vec::new();
        reset_fallback_counts();
        for ev in group {
            M::log_likelihood(ev).expect("log_likelihood");
        }
        let f = fallback_counts();
        line.extend([f.value_calls, f.value_fallbacks]);
        reset_fallback_counts();
        for ev in group {
            M::marginals(ev, &mut marg).expect("marginals");
        }
        let f = fallback_counts();
        line.extend([f.value_calls, f.value_fallbacks, f.posterior_calls, f.posterior_fallbacks]);
        reset_fallback_counts();
        for ev in group {
            let mut st = M::NEW_STATE;
            for (p, row) in ev.iter().enumerate() {
                M::observe(&mut st, p, row).expect("observe");
            }
        }
        let f = fallback_counts();
        line.extend([f.posterior_calls, f.posterior_fallbacks]);
        let line: Vec<String> = line.iter().map(u32::to_string).collect();
        println!("{}", line.join(" "));
    }
}
"#;

/// One group's counts, as the temporary crate prints them: `(calls, fallbacks)` of
/// `log_likelihood`'s value calls, `marginals`' value and posterior calls, and the
/// streaming observes' posterior calls.
struct Counts([(u32, u32); 4]);

impl Counts {
    fn parse(line: &str) -> Counts {
        let v: Vec<u32> = line.split(' ').map(|x| x.parse().unwrap()).collect();
        assert_eq!(v.len(), 8, "a counts line: {line}");
        Counts(std::array::from_fn(|i| (v[2 * i], v[2 * i + 1])))
    }

    /// The cells of the table: the percentage of each kind of call that fell back.
    fn percentages(&self) -> [f64; 4] {
        self.0.map(|(calls, fallbacks)| {
            assert!(
                calls > 0 && fallbacks <= calls,
                "counts {calls} / {fallbacks}"
            );
            100.0 * f64::from(fallbacks) / f64::from(calls)
        })
    }
}

fn workspace() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Writes the temporary crate (the module, `MAIN`, the runtime with its counters) and
/// builds it; returns the binary.
fn build(dir: &Path, source: &str) -> PathBuf {
    let runtime = workspace().join("runtime");
    let manifest = format!(
        "[package]\nname = \"fixed_fallbacks\"\nversion = \"0.0.0\"\nedition = \"2024\"\n\n\
         [dependencies]\ngraphspn-runtime = {{ path = {:?}, features = [\"fallback-counts\"] }}\n\n\
         [workspace]\n\n[profile.release]\nopt-level = 1\ndebug = false\n",
        runtime.display().to_string()
    );
    std::fs::create_dir_all(dir.join("src")).unwrap();
    std::fs::write(dir.join("Cargo.toml"), manifest).unwrap();
    std::fs::write(dir.join("src/map.rs"), source).unwrap();
    std::fs::write(dir.join("src/main.rs"), MAIN).unwrap();
    let target = workspace().join("target/fixed-fallbacks");
    let out = Command::new(env!("CARGO"))
        .args(["build", "--release", "--offline", "--quiet"])
        .env("CARGO_TARGET_DIR", &target)
        .current_dir(dir)
        .output()
        .expect("cargo");
    assert!(
        out.status.success(),
        "build failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    target.join("release/fixed_fallbacks")
}

fn main() {
    // `cargo bench` passes `--bench`; a filter is not used.
    let vectors = std::env::var("GRAPHSPN_FALLBACK_VECTORS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(20usize);
    let demo = workspace().join("generated/demo");
    let builder = Builder::new(
        demo.join("model.json"),
        demo.join("saarbrucken_seq2_night1.json"),
    )
    .vectorisation(Vectorisation::Scalar)
    .arithmetic(Arithmetic::Fixed)
    .seed(0)
    .count(5)
    .module_name("map");
    let inputs = builder.load().expect("demo inputs");
    let source = builder.generate_from(&inputs).expect("fixed-point module");
    let map = &inputs.map;
    // Groups: every place observed, NL1..NL6; then placeholders unobserved.
    let groups: Vec<(NoiseLevel, bool)> = [false, true]
        .into_iter()
        .flat_map(|ph| NoiseLevel::all().map(|l| (l, ph)))
        .collect();
    let mut bytes = Vec::new();
    for &(level, placeholders_unobserved) in &groups {
        for v in 0..vectors {
            let seed = derive_seed(0, &[u64::from(level.get()), v as u64]);
            let ev = simulate_map_evidence(map, level, placeholders_unobserved, seed)
                .expect("the demo map has ground truth");
            for x in ev.rows.iter().flatten() {
                bytes.extend_from_slice(&(*x as f32).to_le_bytes());
            }
        }
    }
    let dir = tempfile::tempdir().unwrap();
    let evidence = dir.path().join("evidence.bin");
    std::fs::write(&evidence, bytes).unwrap();
    let bin = build(dir.path(), &source);
    let run = Command::new(bin)
        .arg(&evidence)
        .arg(vectors.to_string())
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let stdout = String::from_utf8_lossy(&run.stdout);
    let mut table = format!(
        "Fixed-point template calls answered by f32, {} places, {vectors} vectors per row (%):\n\
         | evidence | log_likelihood values | marginals values | marginals posteriors | observe posteriors |\n\
         |---|---|---|---|---|\n",
        map.num_places()
    );
    for (&(level, ph), line) in groups.iter().zip(stdout.lines()) {
        let [a, b, c, d] = Counts::parse(line).percentages();
        let which = if ph { ", placeholders unobserved" } else { "" };
        let _ = writeln!(
            table,
            "| NL{}{which} | {a:.1} | {b:.1} | {c:.1} | {d:.1} |",
            level.get()
        );
    }
    print!("{table}");
}
