//! Time to generate synthetic office floors (the largest supported size, 100,000 places).

use criterion::{Criterion, criterion_group, criterion_main};
use graphspn_compiler::map::synthetic::{SyntheticParams, generate};
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
}

criterion_group!(benches, bench_generator);
criterion_main!(benches);
