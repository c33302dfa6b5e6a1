//! Sum-product loopy belief propagation on a [`FactorGraph`], with the Bethe
//! approximation of `log Z`.
//!
//! # Messages and numerics
//!
//! Messages are stored as natural logs, normalised after every update so that
//! `Σ_s exp(m(s)) = 1` (factor → variable) or `max_s m(s) = 0` (variable →
//! factor). Exact zeros are `-inf` and stay exact. A factor → variable message
//! is computed on a fast linear path (the factor table scaled to max 1 times the
//! incoming messages scaled to max 1) only when no product can leave the
//! normal `f64` range: every positive table entry and every non-zero incoming
//! message entry must lie within `exp(-690 / arity)` of its maximum. Otherwise
//! the message is computed entirely in log space (log-sum-exp). Potentials as
//! small as `1e-300`, or exact zeros, therefore never underflow a message to an
//! all-zero vector as long as a consistent state exists for BP to find; if one
//! does become all-zero, BP stops with [`MrfError::Contradiction`].
//!
//! # Schedules
//!
//! - [`Schedule::Parallel`] (flooding): every variable → factor message is
//!   computed from the previous sweep's factor → variable messages, then every
//!   factor → variable message from those.
//! - [`Schedule::Sequential`]: factors are visited in id order; for each, its
//!   incoming variable → factor messages are recomputed from the *current*
//!   factor → variable messages (including those already updated in this
//!   sweep), then its outgoing messages are updated immediately. This usually
//!   converges in fewer sweeps (libDAI's `SEQFIX` is the same idea).
//!
//! # Damping and convergence
//!
//! With damping `d`, an updated factor → variable message is
//! `(1 − d) · new + d · old` in probability space. One *iteration* is one
//! sweep over all factors. BP has converged when the largest absolute change of
//! any factor → variable message entry (as a probability) in a sweep is below
//! `tolerance`; otherwise it stops after `max_iterations` sweeps and reports
//! `converged = false` with the beliefs it has.
//!
//! # Bethe free energy
//!
//! From the final messages, factor beliefs `b_a(x_a) ∝ f_a(x_a) ∏_{i∈a} m_{i→a}(x_i)`
//! and variable beliefs `b_i(x_i) ∝ ∏_{a∋i} m_{a→i}(x_i)`,
//! `F = Σ_a Σ_x b_a (ln b_a − ln f_a) − Σ_i (d_i − 1) Σ_x b_i ln b_i`
//! (`d_i` = number of factors on `i`, `0 · ln 0 = 0`), and `log Z_Bethe = −F`.
//! On a tree (acyclic factor graph) at convergence this equals the exact `ln Z`.

// Message code walks several parallel arrays by state index; index loops read best.
#![allow(clippy::needless_range_loop)]

use super::MrfError;
use super::factor_graph::FactorGraph;
use std::collections::BTreeMap;
use std::sync::Arc;

/// Largest arity of a factor BP accepts.
pub const MAX_ARITY: usize = 3;

/// The order in which messages are updated; see the module docs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Schedule {
    /// All messages from the previous sweep's messages (flooding).
    Parallel,
    /// Factor by factor, each using the freshest messages.
    #[default]
    Sequential,
}

/// Options of loopy belief propagation.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BpOptions {
    /// Damping `d ∈ [0, 1)`: new message = `(1 − d)·update + d·old` (probabilities).
    pub damping: f64,
    /// Convergence threshold on the largest change of a message entry in one sweep
    /// (finite, in (0, 1]).
    pub tolerance: f64,
    /// Largest number of sweeps (1 to 1,000,000).
    pub max_iterations: usize,
    /// Update order.
    pub schedule: Schedule,
}

impl Default for BpOptions {
    /// No damping, tolerance `1e-9`, 1000 sweeps, sequential schedule (libDAI-like defaults).
    fn default() -> Self {
        BpOptions {
            damping: 0.0,
            tolerance: 1e-9,
            max_iterations: 1000,
            schedule: Schedule::Sequential,
        }
    }
}

impl BpOptions {
    /// Every numeric option against its documented domain (the one check: BP, the
    /// command line and settings files call it).
    pub fn check(&self) -> Result<(), crate::domain::DomainError> {
        use crate::domain::{self, End};
        domain::real(
            "damping",
            self.damping,
            (0.0, End::Closed),
            (1.0, End::Open),
        )?;
        domain::left_open("tolerance", self.tolerance, 0.0, 1.0)?;
        domain::count("max_iterations", self.max_iterations as u64, 1, 1_000_000)
    }

    fn validate(&self) -> Result<(), MrfError> {
        self.check()
            .map_err(|e| MrfError::BadOptions(e.to_string()))
    }
}

/// The outcome of loopy belief propagation.
#[derive(Clone, Debug, PartialEq)]
pub struct BpResult {
    /// Approximate marginals `P(x_i = s)` (variable beliefs), each row sums to 1.
    pub marginals: Vec<Vec<f64>>,
    /// Whether the largest message change fell below the tolerance.
    pub converged: bool,
    /// Number of sweeps performed.
    pub iterations: usize,
    /// Largest message change in the last sweep.
    pub final_change: f64,
    /// `log Z_Bethe = −F_Bethe` from the final beliefs (natural log; exact on trees).
    pub log_z_bethe: f64,
}

/// A table prepared for BP: scaled to max 1, its log, and whether it is "wide".
type PreparedTable = (Arc<[f64]>, Arc<[f64]>, bool);

/// Precomputed per-factor data.
struct FactorData {
    vars: Vec<usize>,
    /// `cards` of `vars`.
    cards: Vec<usize>,
    /// Table scaled to max 1.
    lin: Arc<[f64]>,
    /// Natural log of the table.
    log: Arc<[f64]>,
    /// Some positive entry is below `exp(-690/arity)` of the max: always use the log path.
    wide: bool,
    /// First edge id of this factor (edges of a factor are consecutive).
    first_edge: usize,
}

/// Loopy belief propagation state over a factor graph.
struct Bp<'a> {
    fg: &'a FactorGraph,
    factors: Vec<FactorData>,
    /// `edge_off[e]`: start of edge `e`'s message in the flat arrays.
    edge_off: Vec<usize>,
    edge_var: Vec<usize>,
    /// `var_edges[i]`: edges touching variable `i`.
    var_edges: Vec<Vec<usize>>,
    f2v: Vec<f64>,
    v2f: Vec<f64>,
}

/// Runs sum-product loopy BP; see the module docs for the algorithm and numerics.
///
/// Errors: invalid options, a factor of arity above [`MAX_ARITY`], or a
/// contradiction (a message or belief with no positive entry).
pub fn loopy_bp(fg: &FactorGraph, opts: &BpOptions) -> Result<BpResult, MrfError> {
    opts.validate()?;
    let mut bp = Bp::new(fg)?;
    let mut converged = false;
    let mut iterations = 0;
    let mut change = f64::INFINITY;
    let mut scratch = Scratch::default();
    while iterations < opts.max_iterations {
        iterations += 1;
        change = match opts.schedule {
            Schedule::Parallel => bp.sweep_parallel(opts.damping, iterations, &mut scratch)?,
            Schedule::Sequential => bp.sweep_sequential(opts.damping, iterations, &mut scratch)?,
        };
        if change < opts.tolerance {
            converged = true;
            break;
        }
    }
    // Fresh variable → factor messages from the final factor → variable messages.
    for i in 0..fg.num_vars() {
        bp.update_v2f_of_var(i, iterations, &mut scratch)?;
    }
    let (marginals, log_z_bethe) = bp.beliefs_and_bethe(iterations)?;
    Ok(BpResult {
        marginals,
        converged,
        iterations,
        final_change: change,
        log_z_bethe,
    })
}

#[derive(Default)]
struct Scratch {
    pre: Vec<f64>,
    lin_in: [Vec<f64>; MAX_ARITY],
    log_in: [Vec<f64>; MAX_ARITY],
    out: [Vec<f64>; MAX_ARITY],
}

impl<'a> Bp<'a> {
    fn new(fg: &'a FactorGraph) -> Result<Self, MrfError> {
        let cards = fg.cards();
        let mut factors = Vec::with_capacity(fg.factors().len());
        let mut edge_off = Vec::new();
        let mut edge_var = Vec::new();
        let mut var_edges = vec![Vec::new(); fg.num_vars()];
        let mut off = 0;
        let mut prepared: BTreeMap<(usize, usize), PreparedTable> = BTreeMap::new();
        for (a, f) in fg.factors().iter().enumerate() {
            let arity = f.vars().len();
            if arity > MAX_ARITY {
                return Err(MrfError::ArityTooLarge {
                    factor: a,
                    arity,
                    max: MAX_ARITY,
                });
            }
            // Prepare each distinct (shared) table once.
            let key = (Arc::as_ptr(f.shared_table()) as *const f64 as usize, arity);
            let (lin, log, wide) = prepared
                .entry(key)
                .or_insert_with(|| {
                    let max = f.table().iter().cloned().fold(0.0, f64::max);
                    let lin: Arc<[f64]> = if max > 0.0 {
                        f.table().iter().map(|&x| x / max).collect()
                    } else {
                        vec![0.0; f.table().len()].into()
                    };
                    let limit = (-690.0 / arity as f64).exp();
                    let wide = lin.iter().any(|&x| x > 0.0 && x < limit);
                    let log: Arc<[f64]> = f.table().iter().map(|x| x.ln()).collect();
                    (lin, log, wide)
                })
                .clone();
            let first_edge = edge_off.len();
            for &v in f.vars() {
                var_edges[v].push(edge_off.len());
                edge_off.push(off);
                edge_var.push(v);
                off += cards[v];
            }
            factors.push(FactorData {
                vars: f.vars().to_vec(),
                cards: f.vars().iter().map(|&v| cards[v]).collect(),
                lin,
                log,
                wide,
                first_edge,
            });
        }
        let mut f2v = vec![0.0; off];
        for (e, &v) in edge_var.iter().enumerate() {
            let u = -(cards[v] as f64).ln();
            f2v[edge_off[e]..edge_off[e] + cards[v]].fill(u);
        }
        // A unary factor's outgoing message never depends on other messages: start
        // it at its final value (the normalised table), so evidence is felt from
        // the first update on. Otherwise the first sweep propagates the pairwise
        // prior alone and can lock BP into an evidence-free fixed point.
        for (a, f) in fg.factors().iter().enumerate() {
            if f.vars().len() == 1 {
                let lse = log_sum_exp(&factors[a].log);
                if lse > f64::NEG_INFINITY {
                    let o = edge_off[factors[a].first_edge];
                    for (x, l) in factors[a].log.iter().enumerate() {
                        f2v[o + x] = l - lse;
                    }
                }
            }
        }
        let v2f = vec![0.0; off];
        Ok(Bp {
            fg,
            factors,
            edge_off,
            edge_var,
            var_edges,
            f2v,
            v2f,
        })
    }

    fn card_of_edge(&self, e: usize) -> usize {
        self.fg.cards()[self.edge_var[e]]
    }

    /// Recomputes every variable → factor message of variable `i` (prefix/suffix sums).
    fn update_v2f_of_var(&mut self, i: usize, it: usize, s: &mut Scratch) -> Result<(), MrfError> {
        let c = self.fg.cards()[i];
        let edges = &self.var_edges[i];
        let d = edges.len();
        s.pre.clear();
        s.pre.resize((d + 1) * c, 0.0);
        for (j, &e) in edges.iter().enumerate() {
            let o = self.edge_off[e];
            for x in 0..c {
                s.pre[(j + 1) * c + x] = s.pre[j * c + x] + self.f2v[o + x];
            }
        }
        // Walk back with a running suffix sum.
        let mut suf = vec![0.0; c];
        for (j, &e) in edges.iter().enumerate().rev() {
            let o = self.edge_off[e];
            let mut m = f64::NEG_INFINITY;
            for x in 0..c {
                let v = s.pre[j * c + x] + suf[x];
                self.v2f[o + x] = v;
                m = m.max(v);
            }
            if m == f64::NEG_INFINITY {
                return Err(MrfError::Contradiction {
                    var: i,
                    factor: None,
                    iteration: it,
                });
            }
            for x in 0..c {
                self.v2f[o + x] -= m;
                suf[x] += self.f2v[o + x];
            }
        }
        Ok(())
    }

    /// Recomputes the variable → factor message on edge `e` from the current
    /// factor → variable messages (used by the sequential schedule).
    fn update_v2f_edge(&mut self, e: usize, it: usize) -> Result<(), MrfError> {
        let i = self.edge_var[e];
        let c = self.card_of_edge(e);
        let o = self.edge_off[e];
        self.v2f[o..o + c].fill(0.0);
        for &e2 in &self.var_edges[i] {
            if e2 == e {
                continue;
            }
            let o2 = self.edge_off[e2];
            for x in 0..c {
                self.v2f[o + x] += self.f2v[o2 + x];
            }
        }
        let m = self.v2f[o..o + c]
            .iter()
            .cloned()
            .fold(f64::NEG_INFINITY, f64::max);
        if m == f64::NEG_INFINITY {
            return Err(MrfError::Contradiction {
                var: i,
                factor: None,
                iteration: it,
            });
        }
        self.v2f[o..o + c].iter_mut().for_each(|v| *v -= m);
        Ok(())
    }

    /// Updates the factor → variable messages of factor `a` from the current
    /// variable → factor messages; returns the largest change.
    fn update_factor(
        &mut self,
        a: usize,
        damping: f64,
        it: usize,
        s: &mut Scratch,
    ) -> Result<f64, MrfError> {
        let fd = &self.factors[a];
        let arity = fd.vars.len();
        let limit_log = -690.0 / arity as f64;
        let mut log_path = fd.wide;
        for k in 0..arity {
            let e = fd.first_edge + k;
            let o = self.edge_off[e];
            let c = fd.cards[k];
            let msg = &self.v2f[o..o + c];
            // v2f messages have max exactly 0.
            s.log_in[k].clear();
            s.log_in[k].extend_from_slice(msg);
            s.lin_in[k].clear();
            s.lin_in[k].extend(msg.iter().map(|&l| {
                if l.is_finite() && l < limit_log {
                    log_path = true;
                }
                l.exp()
            }));
            s.out[k].clear();
        }
        if log_path {
            factor_messages_log(fd, &s.log_in, &mut s.out);
        } else {
            factor_messages_lin(fd, &s.lin_in, &mut s.out);
            for k in 0..arity {
                let sum: f64 = s.out[k].iter().sum();
                if sum > 0.0 {
                    let ls = sum.ln();
                    s.out[k].iter_mut().for_each(|x| *x = x.ln() - ls);
                } else {
                    s.out[k].iter_mut().for_each(|x| *x = f64::NEG_INFINITY);
                }
            }
        }
        // s.out now holds normalised log messages; damp and store.
        let mut change: f64 = 0.0;
        for k in 0..arity {
            let e = fd.first_edge + k;
            let o = self.edge_off[e];
            let c = fd.cards[k];
            if s.out[k].iter().all(|&x| x == f64::NEG_INFINITY) {
                return Err(MrfError::Contradiction {
                    var: fd.vars[k],
                    factor: Some(a),
                    iteration: it,
                });
            }
            if damping > 0.0 {
                let mut total = 0.0;
                for x in 0..c {
                    let p = (1.0 - damping) * s.out[k][x].exp() + damping * self.f2v[o + x].exp();
                    s.out[k][x] = p;
                    total += p;
                }
                for x in 0..c {
                    s.out[k][x] = (s.out[k][x] / total).ln();
                }
            }
            for x in 0..c {
                let new = s.out[k][x];
                let old = self.f2v[o + x];
                change = change.max((new.exp() - old.exp()).abs());
                self.f2v[o + x] = new;
            }
        }
        Ok(change)
    }

    fn sweep_parallel(
        &mut self,
        damping: f64,
        it: usize,
        s: &mut Scratch,
    ) -> Result<f64, MrfError> {
        for i in 0..self.fg.num_vars() {
            self.update_v2f_of_var(i, it, s)?;
        }
        let mut change: f64 = 0.0;
        for a in 0..self.factors.len() {
            change = change.max(self.update_factor(a, damping, it, s)?);
        }
        Ok(change)
    }

    fn sweep_sequential(
        &mut self,
        damping: f64,
        it: usize,
        s: &mut Scratch,
    ) -> Result<f64, MrfError> {
        let mut change: f64 = 0.0;
        for a in 0..self.factors.len() {
            let first = self.factors[a].first_edge;
            for k in 0..self.factors[a].vars.len() {
                self.update_v2f_edge(first + k, it)?;
            }
            change = change.max(self.update_factor(a, damping, it, s)?);
        }
        Ok(change)
    }

    /// Variable beliefs and the Bethe log partition function.
    fn beliefs_and_bethe(&self, it: usize) -> Result<(Vec<Vec<f64>>, f64), MrfError> {
        let cards = self.fg.cards();
        let mut marginals = Vec::with_capacity(cards.len());
        let mut free_energy = 0.0;
        for (i, &c) in cards.iter().enumerate() {
            let mut lb = vec![0.0; c];
            for &e in &self.var_edges[i] {
                let o = self.edge_off[e];
                for x in 0..c {
                    lb[x] += self.f2v[o + x];
                }
            }
            let lse = log_sum_exp(&lb);
            if lse == f64::NEG_INFINITY {
                return Err(MrfError::Contradiction {
                    var: i,
                    factor: None,
                    iteration: it,
                });
            }
            let b: Vec<f64> = lb.iter().map(|&l| (l - lse).exp()).collect();
            let neg_entropy: f64 = lb
                .iter()
                .zip(&b)
                .filter(|(_, p)| **p > 0.0)
                .map(|(&l, &p)| p * (l - lse))
                .sum();
            let d = self.var_edges[i].len() as f64;
            free_energy -= (d - 1.0) * neg_entropy;
            marginals.push(b);
        }
        let mut u: Vec<f64> = Vec::new();
        for (a, fd) in self.factors.iter().enumerate() {
            // u(x) = Σ_k v2f_k(x_k); ln b_a(x) = ln f(x) + u(x) − lse, and
            // Σ_x b (ln b − ln f) = Σ_x b (u − lse) (no cancellation with ln f).
            u.clear();
            let arity = fd.vars.len();
            let m: Vec<&[f64]> = (0..arity)
                .map(|k| {
                    let o = self.edge_off[fd.first_edge + k];
                    &self.v2f[o..o + fd.cards[k]]
                })
                .collect();
            match arity {
                1 => u.extend_from_slice(m[0]),
                2 => {
                    for &a0 in m[0] {
                        u.extend(m[1].iter().map(|&a1| a0 + a1));
                    }
                }
                _ => {
                    for &a0 in m[0] {
                        for &a1 in m[1] {
                            u.extend(m[2].iter().map(|&a2| a0 + a1 + a2));
                        }
                    }
                }
            }
            let mut mx = f64::NEG_INFINITY;
            for (lf, ux) in fd.log.iter().zip(u.iter()) {
                mx = mx.max(lf + ux);
            }
            if mx == f64::NEG_INFINITY {
                return Err(MrfError::Contradiction {
                    var: fd.vars[0],
                    factor: Some(a),
                    iteration: it,
                });
            }
            let (mut z, mut zu) = (0.0, 0.0);
            for (lf, ux) in fd.log.iter().zip(u.iter()) {
                let e = (lf + ux - mx).exp();
                if e > 0.0 {
                    z += e;
                    zu += e * ux;
                }
            }
            let lse = mx + z.ln();
            free_energy += zu / z - lse;
        }
        Ok((marginals, -free_energy))
    }
}

/// `ln Σ exp(v)`, `-inf` for an empty or all-`-inf` slice.
pub fn log_sum_exp(v: &[f64]) -> f64 {
    let m = v.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    if m == f64::NEG_INFINITY {
        return m;
    }
    m + v.iter().map(|&x| (x - m).exp()).sum::<f64>().ln()
}

/// Linear-space outgoing messages (unnormalised) of a factor.
fn factor_messages_lin(
    fd: &FactorData,
    lin: &[Vec<f64>; MAX_ARITY],
    out: &mut [Vec<f64>; MAX_ARITY],
) {
    let t = &fd.lin;
    match fd.vars.len() {
        1 => {
            out[0].extend_from_slice(t);
        }
        2 => {
            let (c0, c1) = (fd.cards[0], fd.cards[1]);
            out[0].resize(c0, 0.0);
            out[1].resize(c1, 0.0);
            for x0 in 0..c0 {
                let row = &t[x0 * c1..(x0 + 1) * c1];
                let m0 = lin[0][x0];
                let mut acc0 = 0.0;
                for x1 in 0..c1 {
                    let f = row[x1];
                    acc0 += f * lin[1][x1];
                    out[1][x1] += f * m0;
                }
                out[0][x0] = acc0;
            }
        }
        _ => {
            let (c0, c1, c2) = (fd.cards[0], fd.cards[1], fd.cards[2]);
            out[0].resize(c0, 0.0);
            out[1].resize(c1, 0.0);
            out[2].resize(c2, 0.0);
            for x0 in 0..c0 {
                let m0 = lin[0][x0];
                let mut acc0 = 0.0;
                for x1 in 0..c1 {
                    let m1 = lin[1][x1];
                    let row = &t[(x0 * c1 + x1) * c2..(x0 * c1 + x1 + 1) * c2];
                    let m01 = m0 * m1;
                    let mut acc = 0.0;
                    for x2 in 0..c2 {
                        let f = row[x2];
                        acc += f * lin[2][x2];
                        out[2][x2] += f * m01;
                    }
                    acc0 += acc * m1;
                    out[1][x1] += acc * m0;
                }
                out[0][x0] = acc0;
            }
        }
    }
}

/// Log-space outgoing messages (normalised) of a factor.
fn factor_messages_log(
    fd: &FactorData,
    lg: &[Vec<f64>; MAX_ARITY],
    out: &mut [Vec<f64>; MAX_ARITY],
) {
    let arity = fd.vars.len();
    let n = fd.log.len();
    // Pass 1: per-target, per-state maximum; pass 2: sum of exponentials.
    let mut maxs: Vec<Vec<f64>> = fd
        .cards
        .iter()
        .map(|&c| vec![f64::NEG_INFINITY; c])
        .collect();
    let mut x = [0usize; MAX_ARITY];
    let term = |x: &[usize; MAX_ARITY], j: usize, k: usize| -> f64 {
        let mut t = fd.log[j];
        for (q, xq) in x.iter().enumerate().take(arity) {
            if q != k {
                t += lg[q][*xq];
            }
        }
        t
    };
    for j in 0..n {
        for k in 0..arity {
            let t = term(&x, j, k);
            if t > maxs[k][x[k]] {
                maxs[k][x[k]] = t;
            }
        }
        super::factor_graph::odometer(&mut x[..arity], &fd.cards);
    }
    for k in 0..arity {
        out[k].clear();
        out[k].resize(fd.cards[k], 0.0);
    }
    for j in 0..n {
        for k in 0..arity {
            let m = maxs[k][x[k]];
            if m > f64::NEG_INFINITY {
                out[k][x[k]] += (term(&x, j, k) - m).exp();
            }
        }
        super::factor_graph::odometer(&mut x[..arity], &fd.cards);
    }
    for k in 0..arity {
        for (o, &m) in out[k].iter_mut().zip(&maxs[k]) {
            *o = if m > f64::NEG_INFINITY {
                m + o.ln()
            } else {
                f64::NEG_INFINITY
            };
        }
        let lse = log_sum_exp(&out[k]);
        if lse > f64::NEG_INFINITY {
            out[k].iter_mut().for_each(|o| *o -= lse);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An impossible factor (every entry 0) sends messages of zeros, `-inf` in the log
    /// path, never NaN: no normalisation of an all-`-inf` message (`-inf - -inf`).
    #[test]
    fn an_impossible_factor_sends_zero_messages_not_nan() {
        let cards = vec![2, 3];
        let fd = FactorData {
            vars: vec![0, 1],
            cards: cards.clone(),
            lin: vec![0.0; 6].into(),
            log: vec![f64::NEG_INFINITY; 6].into(),
            wide: false,
            first_edge: 0,
        };
        let mut log_in: [Vec<f64>; MAX_ARITY] = Default::default();
        log_in[0] = vec![0.0, -1.0];
        log_in[1] = vec![-0.5, 0.0, -2.0];
        let mut out: [Vec<f64>; MAX_ARITY] = Default::default();
        factor_messages_log(&fd, &log_in, &mut out);
        for (k, &c) in cards.iter().enumerate() {
            assert_eq!(out[k].len(), c);
            assert!(
                out[k].iter().all(|&v| v == f64::NEG_INFINITY),
                "target {k}: {:?}",
                out[k]
            );
        }
    }

    /// The log path gives the linear path's messages, normalised (`log Σ exp = 0`), for
    /// factors of every arity.
    #[test]
    fn log_and_linear_factor_messages_agree_and_are_normalised() {
        let mut x = 5u64;
        let mut next = || {
            x = x
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (x >> 11) as f64 / (1u64 << 53) as f64
        };
        for cards in [vec![3], vec![2, 4], vec![2, 3, 4]] {
            let n: usize = cards.iter().product();
            let table: Vec<f64> = (0..n).map(|_| 0.05 + next()).collect();
            let max = table.iter().copied().fold(0.0, f64::max);
            let fd = FactorData {
                vars: (0..cards.len()).collect(),
                cards: cards.clone(),
                lin: table.iter().map(|t| t / max).collect(),
                log: table.iter().map(|t| t.ln()).collect(),
                wide: false,
                first_edge: 0,
            };
            let mut log_in: [Vec<f64>; MAX_ARITY] = Default::default();
            let mut lin_in: [Vec<f64>; MAX_ARITY] = Default::default();
            for (k, &c) in cards.iter().enumerate() {
                let m: Vec<f64> = (0..c).map(|_| -3.0 * next()).collect();
                let top = m.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                log_in[k] = m.iter().map(|v| v - top).collect();
                lin_in[k] = log_in[k].iter().map(|v| v.exp()).collect();
            }
            let mut by_log: [Vec<f64>; MAX_ARITY] = Default::default();
            let mut by_lin: [Vec<f64>; MAX_ARITY] = Default::default();
            factor_messages_log(&fd, &log_in, &mut by_log);
            factor_messages_lin(&fd, &lin_in, &mut by_lin);
            for k in 0..cards.len() {
                let sum: f64 = by_lin[k].iter().sum();
                let lse = log_sum_exp(&by_log[k]);
                assert!(lse.abs() < 1e-12, "{cards:?} target {k}: log Σ exp = {lse}");
                for (a, b) in by_log[k].iter().zip(&by_lin[k]) {
                    assert!((a - (b / sum).ln()).abs() < 1e-12, "{cards:?} target {k}");
                }
            }
        }
    }
}
