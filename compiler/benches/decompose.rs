//! Decomposition speed on ~100,000-place maps with the paper's templates:
//! one random decomposition, and the authors' best 5 of 15.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use graphspn_compiler::decompose::synthetic::{grid_map, random_connected_map};
use graphspn_compiler::decompose::{DecompositionParams, decompose, decompose_best};
use graphspn_compiler::template::Template;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

fn bench(c: &mut Criterion) {
    let templates = Template::paper_set();
    let maps = [
        grid_map(316, 316, true),
        random_connected_map(100_000, 8, 200_000, 1),
    ];
    let mut group = c.benchmark_group("decompose");
    group.sample_size(10);
    for map in &maps {
        let name = format!(
            "{} ({} places, {} edges)",
            map.name,
            map.num_places(),
            map.num_edges()
        );
        group.bench_function(format!("single/{name}"), |b| {
            b.iter(|| {
                let mut rng = ChaCha8Rng::seed_from_u64(7);
                black_box(decompose(map, &templates, &mut rng).unwrap())
            })
        });
        group.bench_function(format!("best5of15/{name}"), |b| {
            b.iter(|| {
                let params = DecompositionParams {
                    seed: 7,
                    ..Default::default()
                };
                black_box(decompose_best(map, &templates, &params).unwrap())
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
