//! Time to generate synthetic office floors (the largest supported size, 100,000 places),
//! and to generate one and decompose it as an instance needs (best 5 of 15 candidates,
//! paper templates) — the maps issue asks for under 10 s at 100,000 places.

use criterion::{Criterion, criterion_group, criterion_main};
use graphspn_compiler::decompose::{DecompositionParams, decompose_best};
use graphspn_compiler::map::synthetic::{SyntheticParams, generate};
use graphspn_compiler::template::Template;
use std::hint::black_box;

fn bench_generator(c: &mut Criterion) {
    let mut g = c.benchmark_group("synthetic_generate");
    g.sample_size(10);
    for n in [1_000usize, 10_000, 100_000] {
        g.bench_function(format!("{n}_places"), |b| {
            b.iter(|| {
                let m = generate(&SyntheticParams::new(black_box(n), 1)).expect("generate");
                assert_eq!(m.num_places(), n);
                m
            })
        });
    }
    g.finish();
    let mut g = c.benchmark_group("synthetic_generate_and_decompose");
    g.sample_size(10);
    let templates = Template::paper_set();
    for n in [10_000usize, 100_000] {
        g.bench_function(format!("{n}_places_best5of15"), |b| {
            b.iter(|| {
                let m = generate(&SyntheticParams::new(black_box(n), 1)).expect("generate");
                let ds = decompose_best(&m, &templates, &DecompositionParams::default())
                    .expect("decompose");
                assert_eq!(ds.len(), 5);
                ds
            })
        });
    }
    g.finish();
}

criterion_group!(benches, bench_generator);
criterion_main!(benches);
