//! Training time of the template SPNs on synthetic samples of realistic size
//! (Freiburg + Saarbrucken: ~15k Star, ~30k Three, ~46k Pair samples before
//! augmentation, 10 classes), with the default settings (hard EM, 10 epochs,
//! smoothing 30 → 5, augmentation with the template automorphisms), and with
//! tied symmetric weights. Prints a summary (time, distinct tuples, final
//! log-likelihood per sample, asymmetry under the automorphisms) before the
//! criterion measurements.
//!
//! The synthetic data are a pessimistic case for speed: the Star samples have
//! ~22.6k distinct ordered tuples after augmentation, while all Star matches of
//! the real Freiburg + Saarbrucken maps give at most ~620 (training cost grows
//! with the number of distinct tuples, not with the number of samples).

#[path = "../tests/harness/mod.rs"]
mod harness;

use harness::permutations;
use std::hint::black_box;
use std::time::Instant;

use criterion::{Criterion, criterion_group, criterion_main};
use graphspn_compiler::learn::structure::num_weights;
use graphspn_compiler::learn::train::log_likelihoods;
use graphspn_compiler::learn::{EmKind, Progress, Symmetry, TrainingSettings, learn_template_spn};
use graphspn_compiler::map::ClassId;
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::SeedableRng;

/// Overall class frequencies of the COLD maps (listed in docs/FORMATS.md), index order.
const FREQ: [f64; 10] = [
    0.053, 0.339, 0.109, 0.117, 0.038, 0.102, 0.049, 0.055, 0.051, 0.087,
];

fn draw(rng: &mut ChaCha8Rng, p: &[f64]) -> ClassId {
    let u = rng.random::<f64>() * p.iter().sum::<f64>();
    let mut acc = 0.0;
    for (i, q) in p.iter().enumerate() {
        acc += q;
        if u < acc {
            return i as ClassId;
        }
    }
    (p.len() - 1) as ClassId
}

/// Samples with spatial structure: the pivot's class follows the COLD
/// frequencies; each neighbour keeps the pivot's class with probability 0.4,
/// is a doorway/corridor with probability 0.3, otherwise follows the frequencies.
fn samples(n_vars: usize, m: usize, seed: u64) -> Vec<Vec<ClassId>> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..m)
        .map(|_| {
            let p = draw(&mut rng, &FREQ);
            let mut s = vec![p];
            for _ in 1..n_vars {
                let u = rng.random::<f64>();
                s.push(if u < 0.4 {
                    p
                } else if u < 0.7 {
                    rng.random_range(0..2)
                } else {
                    draw(&mut rng, &FREQ)
                });
            }
            s
        })
        .collect()
}

fn templates() -> Vec<(&'static str, usize, usize, Vec<Vec<usize>>)> {
    let star = permutations(&[1, 2, 3, 4])
        .into_iter()
        .map(|p| [vec![0], p].concat())
        .collect();
    vec![
        ("star", 5, 15_000, star),
        ("three", 3, 30_000, vec![vec![0, 1, 2], vec![0, 2, 1]]),
        ("pair", 2, 46_000, vec![vec![0, 1], vec![1, 0]]),
    ]
}

fn bench(c: &mut Criterion) {
    let mut total = 0.0;
    for (symmetry, em) in [
        (Symmetry::Augment, EmKind::Hard),
        (Symmetry::Tied, EmKind::Hard),
        (Symmetry::Tied, EmKind::Soft),
    ] {
        let settings = TrainingSettings {
            symmetry,
            em,
            ..TrainingSettings::default()
        };
        for (name, n, m, group) in templates() {
            let data = samples(n, m, 1);
            let t = Instant::now();
            let (spn, rep) =
                learn_template_spn(n, 10, &group, &data, &settings, 7, Progress::Hidden)
                    .expect("training");
            let secs = t.elapsed().as_secs_f64();
            total += secs;
            let rep = rep.expect("report");
            // Asymmetry: mean and max |log p(x) − log p(g·x)| over the first 500
            // samples and all automorphisms g.
            let xs: Vec<Vec<ClassId>> = data.iter().take(500).cloned().collect();
            let base = log_likelihoods(&spn, &xs).expect("ll");
            let (mut sum, mut max, mut cnt) = (0.0f64, 0.0f64, 0usize);
            for g in &group {
                let ys: Vec<Vec<ClassId>> = xs
                    .iter()
                    .map(|x| g.iter().map(|&i| x[i]).collect())
                    .collect();
                for (a, b) in base.iter().zip(log_likelihoods(&spn, &ys).expect("ll")) {
                    let d = (a - b).abs();
                    sum += d;
                    max = max.max(d);
                    cnt += 1;
                }
            }
            eprintln!(
                "{symmetry:?} {em:?} {name}: {m} samples ×{} = {} ({} distinct), {} weights, {secs:.3} s, \
                 log-lik/sample initial {:.4} → final {:.4}; asymmetry |Δ log p| mean {:.2e} max {:.2e}",
                group.len(),
                rep.num_samples,
                rep.num_distinct,
                num_weights(&spn),
                rep.initial_log_likelihood,
                rep.log_likelihood_per_epoch
                    .last()
                    .copied()
                    .unwrap_or(f64::NAN),
                sum / cnt as f64,
                max,
            );
        }
    }
    eprintln!("all templates, all three modes: {total:.3} s");

    let mut g = c.benchmark_group("learn");
    g.sample_size(10);
    let settings = TrainingSettings::default();
    for (name, n, m, group) in templates() {
        let data = samples(n, m, 1);
        g.bench_function(format!("train_{name}_{m}"), |b| {
            b.iter(|| {
                black_box(
                    learn_template_spn(n, 10, &group, &data, &settings, 7, Progress::Hidden)
                        .expect("training"),
                )
            })
        });
    }
    g.finish();
}

/// The learning issue's figure: training the whole model on the real Freiburg +
/// Saarbrucken maps (the shipped copy, or `$GRAPHSPN_DATA`). Must stay under 60 s.
fn bench_real(c: &mut Criterion) {
    let dir = graphspn_compiler::map::cold::data_dir(None);
    let mut maps = graphspn_compiler::map::cold::load_building(&dir, "Freiburg").expect("Freiburg");
    maps.extend(
        graphspn_compiler::map::cold::load_building(&dir, "Saarbrucken").expect("Saarbrucken"),
    );
    let templates = graphspn_compiler::template::Template::paper_set();
    let mut g = c.benchmark_group("train_model_real");
    g.sample_size(10);
    g.bench_function("freiburg_saarbrucken_58_maps", |b| {
        b.iter(|| {
            graphspn_compiler::learn::train_model(
                black_box(&maps),
                &templates,
                &TrainingSettings::default(),
                Progress::Hidden,
            )
            .expect("training")
        })
    });
    g.finish();
}

criterion_group!(benches, bench, bench_real);
criterion_main!(benches);
