//! Code size, release build time and run time of generated code as maps grow.
//!
//! Dense paper-sized model (10 classes: Pair 10×10 table, Three 10×10×10 table,
//! Star split {2,2,1} with 5 sums per subset, uniform Singleton; random weights) on
//! grid maps of about 100, 230, 1,000 and 10,000 places with 5 random decompositions.
//! Run: `cargo bench -p graphspn-compiler --bench codegen_scaling` (set
//! `CODEGEN_SIZES=100,230` to choose sizes).

#[path = "../tests/codegen_common/mod.rs"]
mod common;

use std::path::PathBuf;
use std::process::Command;
use std::time::Instant;

use graphspn_compiler::codegen::{CodegenOptions, generate};
use graphspn_compiler::spn::{Node, NodeId, Spn};
use graphspn_compiler::template::Template;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const C: usize = 10;

fn weights(rng: &mut ChaCha8Rng, k: usize) -> Vec<f64> {
    let w: Vec<f64> = (0..k).map(|_| rng.random_range(0.05..1.0)).collect();
    let s: f64 = w.iter().sum();
    w.iter().map(|x| x / s).collect()
}

/// Leaves for `n` vars at ids `v*C + c`.
fn leaves(n: usize) -> Vec<Node> {
    (0..n)
        .flat_map(|v| {
            (0..C).map(move |c| Node::Leaf {
                var: v as u32,
                class: c as u32,
            })
        })
        .collect()
}

/// Full table over `vars`: products of one leaf per var, returns product ids.
fn table(nodes: &mut Vec<Node>, vars: &[usize]) -> Vec<NodeId> {
    let mut ids: Vec<Vec<NodeId>> = vec![vec![]];
    for &v in vars {
        ids = ids
            .into_iter()
            .flat_map(|p| {
                (0..C).map(move |c| {
                    let mut q = p.clone();
                    q.push((v * C + c) as NodeId);
                    q
                })
            })
            .collect();
    }
    ids.into_iter()
        .map(|children| {
            nodes.push(Node::Product { children });
            (nodes.len() - 1) as NodeId
        })
        .collect()
}

fn root_sum(rng: &mut ChaCha8Rng, nodes: &mut Vec<Node>, children: Vec<NodeId>) -> NodeId {
    let w = weights(rng, children.len());
    nodes.push(Node::Sum {
        children,
        weights: w,
    });
    (nodes.len() - 1) as NodeId
}

fn dense_model(seed: u64) -> graphspn_compiler::learn::Model {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    // Star {P,A} {B,C} {D}
    let mut nodes = leaves(5);
    let mut groups: Vec<Vec<NodeId>> = vec![];
    for vars in [&[0usize, 1][..], &[2, 3]] {
        let prods = table(&mut nodes, vars);
        groups.push(
            (0..5)
                .map(|_| root_sum(&mut rng, &mut nodes, prods.clone()))
                .collect(),
        );
    }
    let d_leaves: Vec<NodeId> = (0..C).map(|c| (4 * C + c) as NodeId).collect();
    groups.push(
        (0..5)
            .map(|_| root_sum(&mut rng, &mut nodes, d_leaves.clone()))
            .collect(),
    );
    let mut prods = vec![];
    for &a in &groups[0] {
        for &b in &groups[1] {
            for &c in &groups[2] {
                nodes.push(Node::Product {
                    children: vec![a, b, c],
                });
                prods.push((nodes.len() - 1) as NodeId);
            }
        }
    }
    let root = root_sum(&mut rng, &mut nodes, prods);
    let star = Spn {
        classes: vec![C as u32; 5],
        nodes,
        root,
    };
    let mut spns = vec![star];
    for n in [3usize, 2] {
        let mut nodes = leaves(n);
        let vars: Vec<usize> = (0..n).collect();
        let prods = table(&mut nodes, &vars);
        let root = root_sum(&mut rng, &mut nodes, prods);
        spns.push(Spn {
            classes: vec![C as u32; n],
            nodes,
            root,
        });
    }
    let mut nodes = leaves(1);
    nodes.push(Node::Sum {
        children: (0..C as u32).collect(),
        weights: vec![0.1; C],
    });
    spns.push(Spn {
        classes: vec![C as u32],
        nodes,
        root: C as NodeId,
    });
    common::model(C, Template::paper_set(), spns)
}

const MAIN: &str = r#"
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
    let iters = (1_000_000 / m::NUM_PLACES).max(3);
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
    println!("{:.1} {:.1} {:.1} {}", ll * 1e6, mg * 1e6, mp * 1e6, acc);
}
"#;

fn main() {
    let sizes: Vec<usize> = std::env::var("CODEGEN_SIZES")
        .unwrap_or_else(|_| "100,230,1000,10000".into())
        .split(',')
        .filter_map(|s| s.trim().parse().ok())
        .collect();
    let model = dense_model(1);
    let target = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target/codegen-bench");
    let runtime = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../runtime")
        .canonicalize()
        .expect("runtime folder");
    println!(
        "places | components | gen ms | source KB | build s | binary KB | ll µs | marginals µs | mpe µs"
    );
    for n in sizes {
        let w = (n as f64).sqrt().round() as usize;
        let h = n.div_ceil(w);
        let map = common::grid(w, h, C);
        let decs: Vec<_> = (0..5)
            .map(|s| common::decompose(&map, &model.templates, s))
            .collect();
        let comps: usize = decs.iter().map(|d| d.components.len()).sum();
        let t = Instant::now();
        let src = generate(&model, &map, &decs, &CodegenOptions::default()).expect("generate");
        let gen_ms = t.elapsed().as_secs_f64() * 1e3;
        if std::env::var_os("CODEGEN_KEEP").is_some() {
            let _ = std::fs::create_dir_all(&target);
            let _ = std::fs::write(target.join(format!("m_{n}.rs")), &src);
        }
        if std::env::var_os("CODEGEN_NO_BUILD").is_some() {
            println!(
                "{} | {comps} | {gen_ms:.0} | {} | - | - | - | - | -",
                map.num_places(),
                src.len() / 1024
            );
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
        assert!(st.success());
        let bin = target.join("release/codegen-bench");
        let bin_kb = std::fs::metadata(&bin).expect("binary").len() / 1024;
        let out = Command::new(&bin).output().expect("run");
        let times = String::from_utf8_lossy(&out.stdout).to_string();
        let t: Vec<&str> = times.split_whitespace().collect();
        println!(
            "{} | {comps} | {gen_ms:.0} | {} | {build_s:.1} | {bin_kb} | {} | {} | {}",
            map.num_places(),
            src.len() / 1024,
            t.first().unwrap_or(&"?"),
            t.get(1).unwrap_or(&"?"),
            t.get(2).unwrap_or(&"?")
        );
    }
}
