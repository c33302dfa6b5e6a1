//! Noise-aware training of a tree mixture's potentials: the pairwise potential `ψ`
//! and the unary potential `u` that maximise the conditional log-likelihood of the
//! true labels given noisy evidence, `Σ_graphs Σ_t ln P_t(y* | α)`, over training
//! graphs (annotated maps with simulated evidence), each forest exactly.
//!
//! Each forest is a conditional random field that is log-linear in `θ = (ln ψ, ln u)`
//! (the evidence enters with the model's fixed exponent `γ`), so the objective is
//! concave in `θ`; its gradient is the labels' edge and place counts minus their
//! expectations under `P_t(y | α)` (exact pairwise marginals on the forest's edges).
//! A quadratic penalty `λ/2 ‖θ − θ₀‖²` pulls `θ` towards the counted potentials the
//! model starts from. Maximised by L-BFGS with a backtracking line search, a fixed
//! number of iterations at most: deterministic (graphs are summed in a fixed order).
//!
//! The evidence simulation itself lives with the experiments; this module only sees
//! `(map, forests, rows, truth)`.

use rayon::prelude::*;

use super::TreeMixError;
use super::model::{MAX_POTENTIAL_RATIO, TreeMixture};
use super::trees::{NO_PARENT, SpanningTrees};
use crate::map::{ClassId, TopoMap};

/// One training graph: a map with its forests, evidence rows `α` and true labels.
pub struct FitGraph<'a> {
    /// The annotated map.
    pub map: &'a TopoMap,
    /// Its forests.
    pub trees: &'a SpanningTrees,
    /// Evidence rows (one per place; a row of ones = none).
    pub rows: Vec<Vec<f64>>,
    /// True class of every place.
    pub truth: Vec<ClassId>,
}

/// Options of [`fit_potentials`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FitOptions {
    /// Penalty weight `λ` per parameter, relative to the number of places summed
    /// over (the objective is averaged per place). `> 0`.
    pub penalty: f64,
    /// Largest number of L-BFGS iterations.
    pub iterations: usize,
}

impl Default for FitOptions {
    /// `λ = 1e-3` per place, 60 iterations.
    fn default() -> Self {
        FitOptions {
            penalty: 1e-3,
            iterations: 60,
        }
    }
}

/// What [`fit_potentials`] did.
#[derive(Clone, Debug, PartialEq)]
pub struct FitReport {
    /// Mean conditional log-likelihood per place and forest, before and after.
    pub objective: (f64, f64),
    /// Iterations run.
    pub iterations: usize,
}

/// Parameter layout: the upper triangle of `ln ψ` (row-major, diagonal included),
/// then `ln u`.
fn num_params(c: usize) -> usize {
    c * (c + 1) / 2 + c
}

fn pair_index(c: usize, a: usize, b: usize) -> usize {
    let (a, b) = (a.min(b), a.max(b));
    a * c - a * (a + 1) / 2 + b
}

fn to_params(model: &TreeMixture) -> Vec<f64> {
    let c = model.num_classes();
    let mut th = vec![0.0; num_params(c)];
    for a in 0..c {
        for b in a..c {
            th[pair_index(c, a, b)] = model.psi(a, b).ln();
        }
    }
    for k in 0..c {
        th[c * (c + 1) / 2 + k] = model.unary[k].ln();
    }
    th
}

/// `ψ` and `u` from `θ`, each shifted to a largest entry of 1 and clamped to the
/// model's largest ratio.
fn from_params(c: usize, th: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let clamp = |v: Vec<f64>| -> Vec<f64> {
        let max = v.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
        let floor = -(MAX_POTENTIAL_RATIO.ln()) * 0.999;
        v.into_iter().map(|x| (x - max).max(floor).exp()).collect()
    };
    let mut psi = vec![0.0; c * c];
    for a in 0..c {
        for b in 0..c {
            psi[a * c + b] = th[pair_index(c, a, b)];
        }
    }
    let u = th[c * (c + 1) / 2..].to_vec();
    (clamp(psi), clamp(u))
}

/// The conditional log-likelihood of one graph summed over its forests, and its
/// gradient with respect to `θ` (added into `grad`).
fn graph_cll(
    c: usize,
    gamma: u32,
    psi: &[f64],
    u: &[f64],
    g: &FitGraph<'_>,
    grad: &mut [f64],
) -> f64 {
    let n = g.map.num_places();
    let off = c * (c + 1) / 2;
    // φ_v = u ⊙ (α/max)^γ (scale irrelevant for a conditional likelihood).
    let phi: Vec<Vec<f64>> = g
        .rows
        .iter()
        .map(|row| {
            let max = row.iter().cloned().fold(0.0, f64::max);
            row.iter()
                .zip(u)
                .map(|(&a, &uk)| uk * (a / max).powi(gamma as i32))
                .collect()
        })
        .collect();
    let mut total = 0.0;
    for forest in &g.trees.forests {
        let children = forest.children();
        // Upward: normalised beliefs b_v = φ_v ⊙ Π m_c and messages m_v = ψ b_v.
        let mut msg = vec![Vec::new(); n];
        let mut bel = vec![Vec::new(); n];
        let mut log_z = 0.0;
        for &v in forest.order.iter().rev() {
            let v = v as usize;
            let mut b = phi[v].clone();
            for &ch in &children[v] {
                for (x, m) in b.iter_mut().zip(&msg[ch as usize]) {
                    *x *= m;
                }
            }
            let s: f64 = b.iter().sum();
            b.iter_mut().for_each(|x| *x /= s);
            log_z += s.ln();
            if forest.parent[v] != NO_PARENT {
                let mut m: Vec<f64> = (0..c)
                    .map(|a| (0..c).map(|k| psi[a * c + k] * b[k]).sum())
                    .collect();
                let sm: f64 = m.iter().sum();
                m.iter_mut().for_each(|x| *x /= sm);
                log_z += sm.ln();
                msg[v] = m;
            }
            bel[v] = b;
        }
        // Score of the truth.
        let mut score = 0.0;
        for (v, row) in phi.iter().enumerate() {
            let y = g.truth[v] as usize;
            score += row[y].ln();
            grad[off + y] += 1.0;
            let p = forest.parent[v];
            if p != NO_PARENT {
                let yp = g.truth[p as usize] as usize;
                score += psi[yp * c + y].ln();
                grad[pair_index(c, yp, y)] += 1.0;
            }
        }
        total += score - log_z;
        // Downward: expectations of place and edge indicators.
        let mut down: Vec<Vec<f64>> = vec![Vec::new(); n];
        for &v in &forest.order {
            let v = v as usize;
            let mut full = bel[v].clone();
            if forest.parent[v] != NO_PARENT {
                for (x, d) in full.iter_mut().zip(&down[v]) {
                    *x *= d;
                }
            }
            let s: f64 = full.iter().sum();
            for (k, x) in full.iter().enumerate() {
                grad[off + k] -= x / s;
            }
            for &ch in &children[v] {
                let ch = ch as usize;
                let rest: Vec<f64> = full.iter().zip(&msg[ch]).map(|(x, m)| x / m).collect();
                // Pairwise marginal ∝ rest(a) ψ(a, b) bel_ch(b).
                let mut z = 0.0;
                let mut pm = vec![0.0; c * c];
                for a in 0..c {
                    for b in 0..c {
                        let w = rest[a] * psi[a * c + b] * bel[ch][b];
                        pm[a * c + b] = w;
                        z += w;
                    }
                }
                for a in 0..c {
                    for b in 0..c {
                        grad[pair_index(c, a, b)] -= pm[a * c + b] / z;
                    }
                }
                let mut d: Vec<f64> = (0..c)
                    .map(|b| (0..c).map(|a| psi[a * c + b] * rest[a]).sum())
                    .collect();
                let sd: f64 = d.iter().sum();
                d.iter_mut().for_each(|x| *x /= sd);
                down[ch] = d;
            }
        }
    }
    total
}

/// Mean objective per place and forest, with its gradient (penalty included).
fn objective(
    c: usize,
    gamma: u32,
    th: &[f64],
    th0: &[f64],
    graphs: &[FitGraph<'_>],
    penalty: f64,
) -> (f64, Vec<f64>) {
    let (psi, u) = from_params(c, th);
    let p = num_params(c);
    let parts: Vec<(f64, Vec<f64>, f64)> = graphs
        .par_iter()
        .map(|g| {
            let mut grad = vec![0.0; p];
            let v = graph_cll(c, gamma, &psi, &u, g, &mut grad);
            let weight = (g.map.num_places() * g.trees.len()) as f64;
            (v, grad, weight)
        })
        .collect();
    let count: f64 = parts.iter().map(|x| x.2).sum::<f64>().max(1.0);
    let mut f = 0.0;
    let mut grad = vec![0.0; p];
    for (v, gr, _) in &parts {
        f += v;
        for (a, b) in grad.iter_mut().zip(gr) {
            *a += b;
        }
    }
    f /= count;
    grad.iter_mut().for_each(|x| *x /= count);
    for i in 0..p {
        let d = th[i] - th0[i];
        f -= 0.5 * penalty * d * d;
        grad[i] -= penalty * d;
    }
    (f, grad)
}

/// Fits `model`'s `ψ` and `u` to `graphs` (see the module docs), keeping its
/// exponent, tree count and mixing. The counted potentials of `model` are the
/// starting point and the penalty's centre.
pub fn fit_potentials(
    model: &TreeMixture,
    graphs: &[FitGraph<'_>],
    opts: &FitOptions,
) -> Result<(TreeMixture, FitReport), TreeMixError> {
    if !(opts.penalty.is_finite() && opts.penalty > 0.0) {
        return Err(TreeMixError::Model(format!(
            "fit penalty must be finite and > 0, got {}",
            opts.penalty
        )));
    }
    if graphs.is_empty() {
        return Err(TreeMixError::Model("no training graphs to fit".into()));
    }
    let c = model.num_classes();
    for g in graphs {
        if g.truth.len() != g.map.num_places() || g.rows.len() != g.map.num_places() {
            return Err(TreeMixError::Model(format!(
                "map {}: rows and labels must have one entry per place",
                g.map.name
            )));
        }
        g.trees.check_fits(g.map)?;
    }
    let th0 = to_params(model);
    let gamma = model.evidence_exponent;
    let eval = |th: &[f64]| objective(c, gamma, th, &th0, graphs, opts.penalty);
    let (th, first, last, iterations) = lbfgs_maximise(th0.clone(), &eval, opts.iterations);
    let (psi, u) = from_params(c, &th);
    let mut fitted = model.clone();
    fitted.potential = psi;
    fitted.unary = u;
    fitted
        .check("<fitted model>")
        .map_err(|e| TreeMixError::Model(e.to_string()))?;
    Ok((
        fitted,
        FitReport {
            objective: (first, last),
            iterations,
        },
    ))
}

/// Maximises a smooth concave `f` by L-BFGS (memory 8) with a backtracking
/// (Armijo) line search; returns the argument, the first and last values and the
/// iterations run.
/// A function and its gradient.
type Smooth<'a> = &'a dyn Fn(&[f64]) -> (f64, Vec<f64>);

fn lbfgs_maximise(
    mut x: Vec<f64>,
    f: Smooth<'_>,
    iterations: usize,
) -> (Vec<f64>, f64, f64, usize) {
    const MEMORY: usize = 8;
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let (mut fx, mut g) = f(&x);
    let first = fx;
    let mut hist: Vec<(Vec<f64>, Vec<f64>)> = Vec::new();
    let mut done = 0;
    for _ in 0..iterations {
        // Two-loop recursion on the negated problem (minimise −f).
        let mut q: Vec<f64> = g.iter().map(|v| -v).collect();
        let mut alphas = Vec::with_capacity(hist.len());
        for (s, y) in hist.iter().rev() {
            let rho = 1.0 / dot(y, s);
            let a = rho * dot(s, &q);
            q.iter_mut().zip(y).for_each(|(qi, yi)| *qi -= a * yi);
            alphas.push((a, rho));
        }
        if let Some((s, y)) = hist.last() {
            let gamma = dot(s, y) / dot(y, y);
            q.iter_mut().for_each(|v| *v *= gamma);
        }
        for ((s, y), (a, rho)) in hist.iter().zip(alphas.into_iter().rev()) {
            let b = rho * dot(y, &q);
            q.iter_mut().zip(s).for_each(|(qi, si)| *qi += (a - b) * si);
        }
        // Ascent direction d = −q.
        let d: Vec<f64> = q.iter().map(|v| -v).collect();
        let slope = dot(&g, &d);
        if slope <= 1e-14 {
            break;
        }
        let mut step = if hist.is_empty() {
            1.0 / dot(&g, &g).sqrt().max(1e-12)
        } else {
            1.0
        };
        let mut accepted = None;
        for _ in 0..30 {
            let xn: Vec<f64> = x.iter().zip(&d).map(|(xi, di)| xi + step * di).collect();
            let (fn_, gn) = f(&xn);
            if fn_ >= fx + 1e-4 * step * slope {
                accepted = Some((xn, fn_, gn));
                break;
            }
            step *= 0.5;
        }
        let Some((xn, fn_, gn)) = accepted else { break };
        let s: Vec<f64> = xn.iter().zip(&x).map(|(a, b)| a - b).collect();
        // y for the minimisation of −f: (−gn) − (−g).
        let y: Vec<f64> = g.iter().zip(&gn).map(|(a, b)| a - b).collect();
        if dot(&s, &y) > 1e-12 {
            hist.push((s, y));
            if hist.len() > MEMORY {
                hist.remove(0);
            }
        }
        let gain = fn_ - fx;
        x = xn;
        fx = fn_;
        g = gn;
        done += 1;
        if gain.abs() < 1e-9 * (1.0 + fx.abs()) {
            break;
        }
    }
    (x, first, fx, done)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::decompose::synthetic::random_connected_map;
    use crate::map::ClassSet;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// The analytic gradient matches central finite differences, and the objective
    /// is the brute-force conditional log-likelihood.
    #[test]
    fn gradient_matches_finite_differences() {
        let c = 3;
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let mut map = random_connected_map(6, 4, 3, 9);
        map.classes = ClassSet::new((0..c).map(|k| format!("k{k}")).collect()).unwrap();
        let trees = SpanningTrees::covering(&map, 2, 3).unwrap();
        let g = FitGraph {
            map: &map,
            trees: &trees,
            rows: (0..6)
                .map(|_| (0..c).map(|_| 0.1 + rng.random::<f64>()).collect())
                .collect(),
            truth: (0..6).map(|_| rng.random_range(0..c) as ClassId).collect(),
        };
        let graphs = [g];
        let th: Vec<f64> = (0..num_params(c))
            .map(|_| rng.random::<f64>() - 0.5)
            .collect();
        let th0 = vec![0.0; th.len()];
        let (f, grad) = objective(c, 2, &th, &th0, &graphs, 0.01);
        for i in 0..th.len() {
            let h = 1e-6;
            let mut a = th.clone();
            a[i] += h;
            let mut b = th.clone();
            b[i] -= h;
            let fd = (objective(c, 2, &a, &th0, &graphs, 0.01).0
                - objective(c, 2, &b, &th0, &graphs, 0.01).0)
                / (2.0 * h);
            assert!(
                (fd - grad[i]).abs() < 1e-6,
                "param {i}: {fd} vs {}",
                grad[i]
            );
        }
        // Brute force: Σ_t ln P_t(y* | α) / (places · forests) − penalty.
        let (psi, u) = from_params(c, &th);
        let g = &graphs[0];
        let mut cll = 0.0;
        for f in &g.trees.forests {
            let edges = f.edges();
            let score = |y: &[usize]| -> f64 {
                let mut s = 0.0;
                for v in 0..6 {
                    s += (u[y[v]] * g.rows[v][y[v]].powi(2)).ln();
                }
                for &(a, b) in &edges {
                    s += psi[y[a as usize] * c + y[b as usize]].ln();
                }
                s
            };
            let mut z = 0.0;
            let mut y = vec![0usize; 6];
            loop {
                z += score(&y).exp();
                let mut i = 0;
                while i < 6 && y[i] == c - 1 {
                    y[i] = 0;
                    i += 1;
                }
                if i == 6 {
                    break;
                }
                y[i] += 1;
            }
            let truth: Vec<usize> = g.truth.iter().map(|&t| t as usize).collect();
            cll += score(&truth) - z.ln();
        }
        let pen: f64 = th.iter().map(|x| 0.5 * 0.01 * x * x).sum();
        assert!(
            (f - (cll / 12.0 - pen)).abs() < 1e-9,
            "{f} vs {}",
            cll / 12.0 - pen
        );
    }
}
