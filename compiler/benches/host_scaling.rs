//! Memory and time of host inference (what `graphspn infer --mpe` does, as library
//! calls) on synthetic floors of 1,000 / 10,000 / 100,000 places with the trained demo
//! model, and the cost of one incremental evidence update against a full evaluation.
//!
//! Each size runs in a child process of this binary so its peak resident memory
//! (`VmHWM` of `/proc/self/status`) is its own. Per size: generate the floor (seed 0,
//! as `graphspn generate`), decompose it (best 5 of 15, seed 0) and index the
//! components, set evidence (a random row on every 10th place, seeded), marginals of
//! every place, the MPE labelling. Then 200 single-place updates, each followed by
//! that place's marginal, and one update followed by every place's marginals, against
//! a full evaluation (all evidence set + marginals). The explicit instance SPN (the
//! reference interpreter) is measured at 1,000 places for comparison.
//!
//! Run: `cargo bench -p graphspn-compiler --bench host_scaling` (Linux only: reads
//! `/proc`). Pass sizes after `--` to override, e.g. `-- 1000 10000`.

use std::path::PathBuf;
use std::process::Command;
use std::time::Instant;

use graphspn_compiler::instance::{ComponentInstance, Instance, InstanceModel, InstanceParams};
use graphspn_compiler::interpreter::Evidence;
use graphspn_compiler::learn::Model;
use graphspn_compiler::map::TopoMap;
use graphspn_compiler::map::synthetic::{SyntheticParams, generate};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Peak resident set size of this process in bytes (`VmHWM`).
fn peak_bytes() -> u64 {
    let status = std::fs::read_to_string("/proc/self/status").expect("reading /proc/self/status");
    let line = status
        .lines()
        .find(|l| l.starts_with("VmHWM:"))
        .expect("VmHWM in /proc/self/status");
    let kb: u64 = line
        .split_whitespace()
        .nth(1)
        .and_then(|v| v.parse().ok())
        .expect("VmHWM value");
    kb * 1024
}

fn model() -> Model {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../generated/demo/model.json");
    Model::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// Evidence as an evidence file for `infer` would give it: a random row on every 10th
/// place, ones elsewhere.
fn rows(map: &TopoMap, c: usize, rng: &mut ChaCha8Rng) -> Vec<Vec<f64>> {
    (0..map.num_places())
        .map(|p| {
            if p % 10 == 0 {
                (0..c).map(|_| 0.05 + rng.random::<f64>()).collect()
            } else {
                vec![1.0; c]
            }
        })
        .collect()
}

fn secs(t: Instant) -> f64 {
    t.elapsed().as_secs_f64()
}

/// One size with the component evaluator; prints one `key=value` line.
fn child_components(n: usize) {
    let t0 = Instant::now();
    let model = model();
    let map = generate(&SyntheticParams::new(n, 0)).expect("generate");
    let c = model.classes.len();
    let t_map = secs(t0);
    let t = Instant::now();
    let mut inst =
        ComponentInstance::for_map(&model, &map, &InstanceParams::default()).expect("instance");
    let t_build = secs(t);
    let mut rng = ChaCha8Rng::seed_from_u64(0);
    let ev = rows(&map, c, &mut rng);
    let t = Instant::now();
    inst.set_all_evidence(&ev).expect("evidence");
    let m = inst.marginals().expect("marginals");
    let t_full = secs(t);
    let t = Instant::now();
    let mpe = inst.mpe(&[]).expect("mpe");
    let t_mpe = secs(t);
    let total = secs(t0);
    let peak = peak_bytes();
    assert!(m.log_likelihood.is_finite() && mpe.log_max_product.is_finite());
    // Incremental: one place's evidence changes, then that place's marginal.
    let k = 200;
    let t = Instant::now();
    for _ in 0..k {
        let p = rng.random_range(0..n);
        let row: Vec<f64> = (0..c).map(|_| 0.05 + rng.random::<f64>()).collect();
        inst.set_evidence(p, &row).expect("update");
        std::hint::black_box(inst.marginal(p).expect("marginal"));
    }
    let t_one = secs(t) / k as f64;
    // One update followed by every place's marginals.
    let t = Instant::now();
    let p = rng.random_range(0..n);
    inst.set_evidence(p, &vec![1.0; c]).expect("update");
    std::hint::black_box(inst.marginals().expect("marginals"));
    let t_all = secs(t);
    println!(
        "RESULT places={n} components={} state_mb={:.1} peak_mb={:.1} total_s={:.2} map_s={:.2} build_s={:.2} full_s={:.3} mpe_s={:.3} update_marginal_us={:.1} update_marginals_ms={:.2}",
        inst.num_components(),
        inst.state_bytes() as f64 / 1e6,
        peak as f64 / 1e6,
        total,
        t_map,
        t_build,
        t_full,
        t_mpe,
        t_one * 1e6,
        t_all * 1e3,
    );
}

/// One size with the explicit instance SPN and the interpreter (the reference).
fn child_explicit(n: usize) {
    let t0 = Instant::now();
    let model = model();
    let map = generate(&SyntheticParams::new(n, 0)).expect("generate");
    let c = model.classes.len();
    let inst = Instance::for_map(&model, &map, &InstanceParams::default()).expect("instance");
    let mut im = InstanceModel::new(inst).expect("compile");
    let mut rng = ChaCha8Rng::seed_from_u64(0);
    let ev = Evidence::from_rows(rows(&map, c, &mut rng));
    im.marginals(&ev).expect("marginals");
    im.mpe(&[], &ev).expect("mpe");
    println!(
        "RESULT places={n} explicit=1 peak_mb={:.1} total_s={:.2}",
        peak_bytes() as f64 / 1e6,
        secs(t0)
    );
}

fn run_child(args: &[&str]) -> String {
    let out = Command::new(std::env::current_exe().expect("current exe"))
        .args(args)
        .output()
        .expect("spawning the measuring child");
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "child {args:?} failed: {}\n{}",
        text,
        String::from_utf8_lossy(&out.stderr)
    );
    text.lines()
        .find(|l| l.starts_with("RESULT "))
        .map(|l| l["RESULT ".len()..].to_string())
        .expect("a RESULT line from the child")
}

fn field(line: &str, key: &str) -> f64 {
    line.split_whitespace()
        .find_map(|kv| kv.strip_prefix(&format!("{key}=")))
        .and_then(|v| v.parse().ok())
        .unwrap_or(f64::NAN)
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if let Some(i) = args.iter().position(|a| a == "--child") {
        child_components(args[i + 1].parse().expect("size"));
        return;
    }
    if let Some(i) = args.iter().position(|a| a == "--explicit") {
        child_explicit(args[i + 1].parse().expect("size"));
        return;
    }
    let mut sizes: Vec<usize> = args.iter().filter_map(|a| a.parse().ok()).collect();
    if sizes.is_empty() {
        sizes = vec![1_000, 10_000, 100_000];
    }
    println!(
        "host inference (decompose + evidence + marginals + MPE), demo model, D = 5, {} threads",
        std::thread::available_parallelism().map_or(1, |n| n.get())
    );
    println!(
        "| places | components | peak memory | total time | of which marginals | MPE | update + marginal(place) | update + marginals(all) | full / update |"
    );
    println!("|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    let mut first: Option<(f64, f64, f64)> = None;
    for &n in &sizes {
        let r = run_child(&["--child", &n.to_string()]);
        let (peak, total, full) = (
            field(&r, "peak_mb"),
            field(&r, "total_s"),
            field(&r, "full_s"),
        );
        let one = field(&r, "update_marginal_us");
        println!(
            "| {n} | {} | {peak:.0} MB | {total:.2} s | {full:.3} s | {:.3} s | {one:.0} µs | {:.1} ms | {:.0}× |",
            field(&r, "components"),
            field(&r, "mpe_s"),
            field(&r, "update_marginals_ms"),
            full / (one * 1e-6),
        );
        if let Some((n0, p0, t0)) = first {
            println!(
                "  vs {n0} places: {:.1}× places, {:.1}× memory, {:.1}× time",
                n as f64 / n0,
                peak / p0,
                total / t0
            );
        } else {
            first = Some((n as f64, peak, total));
        }
    }
    let r = run_child(&["--explicit", "1000"]);
    println!(
        "explicit instance SPN + interpreter (reference) at 1000 places: peak {:.0} MB, {:.2} s",
        field(&r, "peak_mb"),
        field(&r, "total_s")
    );
}
