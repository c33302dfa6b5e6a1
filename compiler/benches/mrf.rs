//! Loopy BP for MRF-2 and MRF-3 on a synthetic 230-node office-like map with
//! 10 classes (the size of the largest COLD map).

use criterion::{Criterion, criterion_group, criterion_main};
use graphspn_compiler::experiments::evidence::{NoiseLevel, simulate_evidence};
use graphspn_compiler::map::{ClassId, ClassSet, Place, TopoMap};
use graphspn_compiler::mrf::{BpOptions, CooccurrenceParams, Mrf2, Mrf3, MrfModel};
use petgraph::graph::UnGraph;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::hint::black_box;

/// A 23 × 10 grid (230 places): 4-neighbour edges plus random diagonals (about
/// 450 edges, mean degree ≈ 4, like the COLD maps). Row 4 is a corridor; the
/// rest is cut into 4-wide "rooms" of random classes, with doorways next to the corridor.
fn synthetic_map(seed: u64) -> TopoMap {
    let (w, h) = (23usize, 10usize);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let room_class: Vec<ClassId> = (0..64).map(|_| rng.random_range(2..10)).collect();
    let mut g = UnGraph::new_undirected();
    for r in 0..h {
        for c in 0..w {
            let class = if r == 4 {
                1
            } else if (r == 3 || r == 5) && c % 4 == 1 {
                0
            } else {
                room_class[(r / 4) * 8 + c / 4]
            };
            g.add_node(Place {
                id: (r * w + c) as u32,
                class: Some(class),
                placeholder: false,
                x: c as f64,
                y: r as f64,
            });
        }
    }
    let id = |r: usize, c: usize| ((r * w + c) as u32).into();
    for r in 0..h {
        for c in 0..w {
            if c + 1 < w {
                g.add_edge(id(r, c), id(r, c + 1), ());
            }
            if r + 1 < h {
                g.add_edge(id(r, c), id(r + 1, c), ());
            }
            if r + 1 < h && c + 1 < w && rng.random_bool(0.1) {
                g.add_edge(id(r, c), id(r + 1, c + 1), ());
            }
        }
    }
    TopoMap {
        name: format!("synthetic-{seed}"),
        classes: ClassSet::paper(),
        graph: g,
    }
}

fn bench(c: &mut Criterion) {
    let train: Vec<TopoMap> = (1..=6).map(synthetic_map).collect();
    let test = synthetic_map(100);
    let truth: Vec<ClassId> = test.places().map(|p| p.class.unwrap()).collect();
    let m2 = Mrf2::train(&train, &CooccurrenceParams::default()).unwrap();
    let m3 = Mrf3::train(&train, &CooccurrenceParams::default()).unwrap();
    let opts = BpOptions::default();
    for level in [2u8, 5] {
        let l = NoiseLevel::new(level).unwrap();
        let ev = simulate_evidence(&truth, 10, &vec![false; truth.len()], &l.params(), 1).unwrap();
        for (name, model) in [("mrf2", &m2 as &dyn MrfModel), ("mrf3", &m3)] {
            let r = model.infer(&test, &ev.rows, &opts).unwrap();
            let acc = r
                .marginals
                .iter()
                .zip(&truth)
                .filter(|(m, t)| {
                    let best = (0..10).fold(0, |b, k| if m[k] > m[b] { k } else { b });
                    best == **t as usize
                })
                .count() as f64
                / truth.len() as f64;
            println!(
                "{name} NL{level}: {} edges, converged {} in {} sweeps, accuracy {:.3}",
                test.num_edges(),
                r.converged,
                r.iterations,
                acc
            );
            c.bench_function(&format!("{name}_infer_230_nodes_nl{level}"), |b| {
                b.iter(|| black_box(model.infer(&test, &ev.rows, &opts).unwrap()))
            });
        }
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = bench
}
criterion_main!(benches);
