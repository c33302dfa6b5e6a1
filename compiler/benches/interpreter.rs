//! Interpreter throughput on dense layered SPNs (`spn::random::layered_spn`, 10 classes,
//! 20 sums per region) of about 250k, 500k and 1M edges: log-likelihood and marginals
//! scale linearly in the edge count; MPE at 1M edges.
//!
//! Run: `cargo bench -p graphspn-compiler --bench interpreter`.

use std::hint::black_box;
use std::time::Duration;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use graphspn_compiler::interpreter::{Evaluator, Evidence};
use graphspn_compiler::spn::random::layered_spn;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn noisy_evidence(classes: &[u32], seed: u64) -> Evidence {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    Evidence::from_rows(
        classes
            .iter()
            .map(|&k| (0..k).map(|_| rng.random_range(0.001..1.0)).collect())
            .collect(),
    )
}

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("interpreter");
    group
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(3));
    // Variables chosen so the edge counts are ~250k, ~500k and ~1M.
    for vars in [29usize, 58, 115] {
        let spn = layered_spn(42, vars, 10, 20);
        let edges = spn.num_edges() as u64;
        let evidence = noisy_evidence(&spn.classes, 7);
        let fixed = vec![None; spn.num_vars()];
        let mut ev = Evaluator::new(&spn).expect("layered SPN is valid");
        group.throughput(Throughput::Elements(edges));
        group.bench_with_input(BenchmarkId::new("log_likelihood", edges), &edges, |b, _| {
            b.iter(|| black_box(ev.log_likelihood(black_box(&fixed), &evidence).unwrap()))
        });
        group.bench_with_input(BenchmarkId::new("marginals", edges), &edges, |b, _| {
            b.iter(|| black_box(ev.marginals(black_box(&fixed), &evidence).unwrap()))
        });
        if vars == 115 {
            group.bench_with_input(BenchmarkId::new("mpe", edges), &edges, |b, _| {
                b.iter(|| black_box(ev.mpe(black_box(&fixed), &evidence).unwrap()))
            });
            group.bench_with_input(BenchmarkId::new("validate", edges), &edges, |b, _| {
                b.iter(|| black_box(&spn).validate().is_ok())
            });
        }
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
