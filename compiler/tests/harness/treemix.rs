//! Tree-mixture fixtures and the brute-force oracle: random models and the exact
//! answers of every query by enumerating all labellings of a small map.

use graphspn_compiler::family::ModelFamily;
use graphspn_compiler::learn::model::MODEL_FORMAT;
use graphspn_compiler::map::{ClassId, ClassSet};
use graphspn_compiler::spn::Mixing;
use graphspn_compiler::treemix::{SpanningTrees, TreeMixture};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A tree mixture over `c` classes named `k0..` with a random symmetric potential
/// and unary (entries in [0.05, 1.05)), `trees` trees, exponent `gamma`.
pub fn random_model(c: usize, trees: usize, gamma: u32, mixing: Mixing, seed: u64) -> TreeMixture {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut potential = vec![0.0; c * c];
    for a in 0..c {
        for b in a..c {
            let v = 0.05 + rng.random::<f64>();
            potential[a * c + b] = v;
            potential[b * c + a] = v;
        }
    }
    TreeMixture {
        format: MODEL_FORMAT,
        family: ModelFamily::TreeMixture,
        classes: ClassSet::new((0..c).map(|k| format!("k{k}")).collect()).unwrap(),
        potential,
        unary: (0..c).map(|_| 0.05 + rng.random::<f64>()).collect(),
        evidence_exponent: gamma,
        trees,
        mixing,
        settings: serde_json::Value::Null,
        trained_on: vec![],
    }
}

/// The exact answers of every query, by enumeration.
#[derive(Clone, Debug)]
pub struct Oracle {
    /// `ln S` with the places of `fixed` clamped.
    pub log_likelihood: f64,
    /// The mixture's marginals (posterior mixing).
    pub posterior: Vec<Vec<f64>>,
    /// The mean of the forests' marginals (average mixing).
    pub average: Vec<Vec<f64>>,
    /// `ln max_t max_y (1/T) P_t(y) Π α^γ`.
    pub log_max_product: f64,
    /// `P(t | α)` of every forest.
    pub weights: Vec<f64>,
}

/// Every labelling of `n` places with `c` classes.
pub fn labellings(n: usize, c: usize) -> Vec<Vec<usize>> {
    let mut out = vec![vec![]];
    for _ in 0..n {
        out = out
            .into_iter()
            .flat_map(|p: Vec<usize>| {
                (0..c).map(move |k| {
                    let mut q = p.clone();
                    q.push(k);
                    q
                })
            })
            .collect();
    }
    out
}

/// Brute-force answers for `model` over `trees` with evidence `rows` (α, not
/// tempered) and places clamped by `fixed`.
pub fn oracle(
    model: &TreeMixture,
    trees: &SpanningTrees,
    rows: &[Vec<f64>],
    fixed: &[Option<ClassId>],
) -> Oracle {
    let c = model.num_classes();
    let n = rows.len();
    let t_count = trees.len();
    let all = labellings(n, c);
    let ev = |y: &[usize]| -> f64 {
        y.iter()
            .enumerate()
            .map(|(v, &k)| match fixed[v] {
                Some(l) if l as usize != k => 0.0,
                _ => rows[v][k].powi(model.evidence_exponent as i32),
            })
            .product()
    };
    let mut post = vec![vec![0.0; c]; n];
    let mut avg = vec![vec![0.0; c]; n];
    let mut s_total = 0.0;
    let mut best = 0.0f64;
    let mut per_tree = Vec::new();
    for f in &trees.forests {
        let edges = f.edges();
        let score = |y: &[usize]| -> f64 {
            let u: f64 = y.iter().map(|&k| model.unary[k]).product();
            let p: f64 = edges
                .iter()
                .map(|&(a, b)| model.psi(y[a as usize], y[b as usize]))
                .product();
            u * p
        };
        let z: f64 = all.iter().map(|y| score(y)).sum();
        let mut s_t = 0.0;
        let mut m_t = vec![vec![0.0; c]; n];
        for y in &all {
            let w = score(y) / z * ev(y);
            s_t += w;
            best = best.max(w / t_count as f64);
            for (v, &k) in y.iter().enumerate() {
                m_t[v][k] += w;
            }
        }
        for v in 0..n {
            for k in 0..c {
                post[v][k] += m_t[v][k];
                avg[v][k] += m_t[v][k] / s_t / t_count as f64;
            }
        }
        s_total += s_t / t_count as f64;
        per_tree.push(s_t / t_count as f64);
    }
    for row in &mut post {
        let s: f64 = row.iter().sum();
        row.iter_mut().for_each(|x| *x /= s);
    }
    Oracle {
        log_likelihood: s_total.ln(),
        posterior: post,
        average: avg,
        log_max_product: best.ln(),
        weights: per_tree.iter().map(|s| s / s_total).collect(),
    }
}
