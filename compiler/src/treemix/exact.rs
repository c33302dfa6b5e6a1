//! Exact inference in the tree mixture of one map, on the host (`f64`).
//!
//! Each forest is evaluated by one upward (and, for marginals, one downward) pass of
//! sum-product messages, `O(places · C²)` per forest; the mixture then combines the
//! forests exactly ([`Mixing::Posterior`]) or averages their exact marginals
//! ([`Mixing::Average`]). Messages and beliefs are renormalised at every place and
//! their scales kept as logs, and every evidence row enters as `u ⊙ (α / max α)^γ`
//! with `γ · ln max α` kept as a log, so no valid evidence underflows: relative error
//! of a few ulps per place and class (every term is non-negative; nothing cancels).
//!
//! This evaluator is what `graphspn infer` and the experiments use; the explicit
//! instance SPN of [`super::spn`] with the interpreter is the independent reference it
//! is tested against (and both against brute-force enumeration on small maps).

use graphspn_runtime::EvidenceError;

use super::TreeMixError;
use super::model::TreeMixture;
use super::trees::{NO_PARENT, SpanningTrees};
use crate::interpreter::{Marginals, Mpe, check_row};
use crate::map::{ClassId, TopoMap};
use crate::spn::Mixing;

const NEG_INF: f64 = f64::NEG_INFINITY;

/// A tree mixture instantiated on one map, with the evidence of every place.
#[derive(Clone, Debug)]
pub struct TreeInstance {
    classes: usize,
    gamma: u32,
    psi: Vec<f64>,
    ln_psi: Vec<f64>,
    unary: Vec<f64>,
    mixing: Mixing,
    trees: SpanningTrees,
    children: Vec<Vec<Vec<u32>>>,
    place_ids: Vec<u64>,
    /// `ln Z_t` of every forest (its value without evidence).
    log_z: Vec<f64>,
    /// The evidence rows α (all ones where a place has none).
    rows: Vec<Vec<f64>>,
}

/// Per-forest marginals and the mixture weights of one query.
#[derive(Clone, Debug, PartialEq)]
pub struct TreeMarginals {
    /// The mixed marginals and `ln S(α)` of the mixture.
    pub mixed: Marginals,
    /// `P(t | α)` of every forest (the posterior mixture weights).
    pub posterior_weights: Vec<f64>,
}

/// One forest's upward pass: normalised messages and beliefs, and the log value.
struct Upward {
    /// Message of every non-root place to its parent (sum 1).
    msg: Vec<Vec<f64>>,
    /// `φ ⊙ ∏ children's messages` of every place (sum 1).
    bel: Vec<Vec<f64>>,
    /// `ln` of the forest's unnormalised value `Σ_y ∏ψ ∏φ` (`-∞` if zero).
    log_value: f64,
}

impl TreeInstance {
    /// The instance of `model` on `map` over `trees` (checked against both), without
    /// evidence.
    pub fn build(
        model: &TreeMixture,
        map: &TopoMap,
        trees: SpanningTrees,
    ) -> Result<Self, TreeMixError> {
        super::check_inputs(model, map, &trees)?;
        let c = model.num_classes();
        let n = map.num_places();
        let children = trees.forests.iter().map(|f| f.children()).collect();
        let mut inst = TreeInstance {
            classes: c,
            gamma: model.evidence_exponent,
            psi: model.potential.clone(),
            ln_psi: model.potential.iter().map(|p| p.ln()).collect(),
            unary: model.unary.clone(),
            mixing: model.mixing,
            trees,
            children,
            place_ids: map.places().map(|p| u64::from(p.id)).collect(),
            log_z: Vec::new(),
            rows: vec![vec![1.0; c]; n],
        };
        let phi = inst.factors(&vec![None; n]);
        inst.log_z = (0..inst.trees.len())
            .map(|t| inst.upward(t, &phi.0).log_value + phi.1)
            .collect();
        Ok(inst)
    }

    /// The instance of `model` on `map` over `model.trees` covering forests drawn
    /// with `seed` ([`SpanningTrees::covering`]).
    pub fn with_covering_trees(
        model: &TreeMixture,
        map: &TopoMap,
        seed: u64,
    ) -> Result<Self, TreeMixError> {
        let trees = SpanningTrees::covering(map, model.trees, seed)?;
        Self::build(model, map, trees)
    }

    /// Number of places.
    pub fn num_places(&self) -> usize {
        self.rows.len()
    }

    /// Number of classes.
    pub fn num_classes(&self) -> usize {
        self.classes
    }

    /// The forests mixed.
    pub fn trees(&self) -> &SpanningTrees {
        &self.trees
    }

    /// `ln Z_t` of every forest: the log of its unnormalised value without evidence.
    pub fn log_partition(&self) -> &[f64] {
        &self.log_z
    }

    /// The evidence rows (ones where a place has none).
    pub fn evidence(&self) -> &[Vec<f64>] {
        &self.rows
    }

    /// The evidence rows raised to the model's exponent, `α^γ`: the evidence of the
    /// explicit instance SPN ([`super::spn::instance_spn`]).
    pub fn tempered_evidence(&self) -> Vec<Vec<f64>> {
        self.rows
            .iter()
            .map(|r| r.iter().map(|a| a.powi(self.gamma as i32)).collect())
            .collect()
    }

    /// The pairwise potential `ψ` (`C × C`) and the unary potential `u` (`C`).
    pub fn potentials(&self) -> (&[f64], &[f64]) {
        (&self.psi, &self.unary)
    }

    fn check_place(&self, place: usize) -> Result<(), TreeMixError> {
        if place >= self.num_places() {
            return Err(TreeMixError::PlaceOutOfRange {
                place,
                count: self.num_places(),
            });
        }
        Ok(())
    }

    /// Sets the evidence of every place (one row per place, place order), each
    /// checked by the interpreter's rules ([`check_row`]); nothing changes on error.
    pub fn set_all_evidence(&mut self, rows: &[Vec<f64>]) -> Result<(), TreeMixError> {
        if rows.len() != self.num_places() {
            return Err(EvidenceError::WrongLength {
                expected: self.num_places(),
                found: rows.len(),
            }
            .into());
        }
        for (p, row) in rows.iter().enumerate() {
            check_row(p, self.place_ids[p], row, self.classes)?;
        }
        self.rows = rows.to_vec();
        Ok(())
    }

    /// Sets the evidence row of place index `place` ([`check_row`] rules).
    pub fn set_evidence(&mut self, place: usize, row: &[f64]) -> Result<(), TreeMixError> {
        self.check_place(place)?;
        check_row(place, self.place_ids[place], row, self.classes)?;
        self.rows[place] = row.to_vec();
        Ok(())
    }

    /// Removes the evidence of place index `place` (a row of ones).
    pub fn clear_evidence(&mut self, place: usize) -> Result<(), TreeMixError> {
        self.check_place(place)?;
        self.rows[place] = vec![1.0; self.classes];
        Ok(())
    }

    /// The factor `φ_v = u ⊙ (α_v / max α_v)^γ` of every place (restricted to its
    /// label where `fixed` has one), and `Σ_v γ · ln max α_v`.
    fn factors(&self, fixed: &[Option<ClassId>]) -> (Vec<Vec<f64>>, f64) {
        let mut log_scale = 0.0;
        let phi = self
            .rows
            .iter()
            .zip(fixed)
            .map(|(row, f)| {
                let max = row.iter().cloned().fold(0.0, f64::max);
                log_scale += f64::from(self.gamma) * max.ln();
                row.iter()
                    .zip(&self.unary)
                    .enumerate()
                    .map(|(k, (&a, &u))| match f {
                        Some(l) if *l as usize != k => 0.0,
                        _ => u * (a / max).powi(self.gamma as i32),
                    })
                    .collect()
            })
            .collect();
        (phi, log_scale)
    }

    /// `m(a) = Σ_b ψ(a, b) x(b)`, and its sum.
    fn times_psi(&self, x: &[f64]) -> (Vec<f64>, f64) {
        let c = self.classes;
        let m: Vec<f64> = (0..c)
            .map(|a| (0..c).map(|b| self.psi[a * c + b] * x[b]).sum())
            .collect();
        let s = m.iter().sum();
        (m, s)
    }

    fn upward(&self, t: usize, phi: &[Vec<f64>]) -> Upward {
        let forest = &self.trees.forests[t];
        let c = self.classes;
        let n = self.num_places();
        let mut msg = vec![Vec::new(); n];
        let mut bel = vec![Vec::new(); n];
        let mut log_value = 0.0;
        for &v in forest.order.iter().rev() {
            let v = v as usize;
            let mut b = phi[v].clone();
            for &ch in &self.children[t][v] {
                for (x, m) in b.iter_mut().zip(&msg[ch as usize]) {
                    *x *= m;
                }
            }
            let s: f64 = b.iter().sum();
            if s == 0.0 {
                return Upward {
                    msg,
                    bel,
                    log_value: NEG_INF,
                };
            }
            b.iter_mut().for_each(|x| *x /= s);
            log_value += s.ln();
            if forest.parent[v] != NO_PARENT {
                let (mut m, sm) = self.times_psi(&b);
                m.iter_mut().for_each(|x| *x /= sm);
                log_value += sm.ln();
                msg[v] = m;
            }
            debug_assert_eq!(b.len(), c);
            bel[v] = b;
        }
        Upward {
            msg,
            bel,
            log_value,
        }
    }

    /// Exact marginals of forest `t` given its upward pass.
    fn downward(&self, t: usize, up: &Upward) -> Vec<Vec<f64>> {
        let forest = &self.trees.forests[t];
        let n = self.num_places();
        let mut down: Vec<Vec<f64>> = vec![Vec::new(); n];
        let mut marg = vec![Vec::new(); n];
        for &v in &forest.order {
            let v = v as usize;
            let mut full = up.bel[v].clone();
            if forest.parent[v] != NO_PARENT {
                for (x, d) in full.iter_mut().zip(&down[v]) {
                    *x *= d;
                }
            }
            let s: f64 = full.iter().sum();
            marg[v] = full.iter().map(|x| x / s).collect();
            for &ch in &self.children[t][v] {
                // The parent's belief without the child's own message (ψ > 0, so
                // every message entry is > 0).
                let rest: Vec<f64> = full
                    .iter()
                    .zip(&up.msg[ch as usize])
                    .map(|(x, m)| x / m)
                    .collect();
                let (mut d, sd) = self.times_psi(&rest);
                d.iter_mut().for_each(|x| *x /= sd);
                down[ch as usize] = d;
            }
        }
        marg
    }

    /// `ln P_t(α)` of every forest (its normalised likelihood of the evidence, with
    /// places clamped by `fixed`), and the upward passes.
    fn tree_values(&self, fixed: &[Option<ClassId>]) -> (Vec<f64>, Vec<Upward>) {
        let (phi, scale) = self.factors(fixed);
        let ups: Vec<Upward> = (0..self.trees.len())
            .map(|t| self.upward(t, &phi))
            .collect();
        let values = ups
            .iter()
            .zip(&self.log_z)
            .map(|(u, z)| u.log_value + scale - z)
            .collect();
        (values, ups)
    }

    /// `ln S`: `ln (1/T) Σ_t P_t(α)`.
    fn mix(&self, values: &[f64]) -> Result<f64, TreeMixError> {
        let m = log_sum_exp(values);
        if m == NEG_INF {
            return Err(EvidenceError::ZeroLikelihood.into());
        }
        Ok(m - (values.len() as f64).ln())
    }

    /// The labelling to evaluate: `fixed` when it is valid, every place summed out
    /// when it is empty (as the GraphSPN evaluators take an empty labelling).
    fn labelling<'a>(
        &self,
        fixed: &'a [Option<ClassId>],
    ) -> Result<std::borrow::Cow<'a, [Option<ClassId>]>, TreeMixError> {
        if fixed.is_empty() {
            return Ok(vec![None; self.num_places()].into());
        }
        if fixed.len() != self.num_places() {
            return Err(TreeMixError::BadLabels(format!(
                "{} labels for {} places",
                fixed.len(),
                self.num_places()
            )));
        }
        if let Some((p, l)) = fixed
            .iter()
            .enumerate()
            .find_map(|(p, l)| l.filter(|&l| l as usize >= self.classes).map(|l| (p, l)))
        {
            return Err(TreeMixError::BadLabels(format!(
                "place index {p} (id {}): class {l} out of range ({} classes)",
                self.place_ids[p], self.classes
            )));
        }
        Ok(fixed.into())
    }

    /// `ln S(α)`: the natural log of the mixture's likelihood of the evidence,
    /// `ln Σ_y P(y) ∏_v α_v(y_v)^γ`. Errors when it is zero.
    pub fn log_likelihood(&self) -> Result<f64, TreeMixError> {
        let fixed = vec![None; self.num_places()];
        self.mix(&self.tree_values(&fixed).0)
    }

    /// `ln S` with every labelled place restricted to its label (`None` = summed out;
    /// an empty slice: none labelled): with no evidence and every place labelled,
    /// `ln P(labels)`.
    pub fn log_likelihood_labelled(&self, fixed: &[Option<ClassId>]) -> Result<f64, TreeMixError> {
        let fixed = self.labelling(fixed)?;
        self.mix(&self.tree_values(&fixed).0)
    }

    /// Exact marginals of every forest on its own (`P_t(Y_v = c | α)`), forest-major.
    pub fn tree_marginals(&self) -> Result<Vec<Vec<Vec<f64>>>, TreeMixError> {
        let fixed = vec![None; self.num_places()];
        let (values, ups) = self.tree_values(&fixed);
        self.mix(&values)?;
        Ok((0..self.trees.len())
            .map(|t| self.downward(t, &ups[t]))
            .collect())
    }

    /// Marginals mixed as the model says ([`TreeInstance::marginals_mixed`]).
    pub fn marginals(&self) -> Result<TreeMarginals, TreeMixError> {
        self.marginals_mixed(self.mixing)
    }

    /// `P(Y_v = c | α)` of every place: with [`Mixing::Posterior`] the exact marginals of
    /// the mixture (each forest weighted by `P(t | α)`), with [`Mixing::Average`] the
    /// mean of the forests' exact marginals; and `ln S(α)` (the mixture's, either way).
    pub fn marginals_mixed(&self, mixing: Mixing) -> Result<TreeMarginals, TreeMixError> {
        let fixed = vec![None; self.num_places()];
        let (values, ups) = self.tree_values(&fixed);
        let ll = self.mix(&values)?;
        let t_count = values.len() as f64;
        let posterior: Vec<f64> = values
            .iter()
            .map(|v| (v - ll - t_count.ln()).exp())
            .collect();
        let weights: Vec<f64> = match mixing {
            Mixing::Posterior => posterior.clone(),
            Mixing::Average => vec![1.0 / t_count; values.len()],
        };
        let mut probs = vec![vec![0.0; self.classes]; self.num_places()];
        for (t, &w) in weights.iter().enumerate() {
            if w == 0.0 {
                continue;
            }
            for (row, m) in probs.iter_mut().zip(self.downward(t, &ups[t])) {
                for (p, x) in row.iter_mut().zip(m) {
                    *p += w * x;
                }
            }
        }
        for row in &mut probs {
            let s: f64 = row.iter().sum();
            row.iter_mut().for_each(|x| *x /= s);
        }
        Ok(TreeMarginals {
            mixed: Marginals {
                log_likelihood: ll,
                probs,
            },
            posterior_weights: posterior,
        })
    }

    /// The most probable `(forest, labelling)` pair: `max_t max_y (1/T) P_t(y) ∏_v
    /// α_v(y_v)^γ` (places in `fixed` keep their label), ties to the first forest and
    /// the smallest class. `log_max_product` is the log of that value;
    /// `log_probability` is `ln S` with every place fixed to the labelling. An empty
    /// `fixed`: no place labelled.
    pub fn mpe(&self, fixed: &[Option<ClassId>]) -> Result<Mpe, TreeMixError> {
        let fixed = self.labelling(fixed)?;
        let (phi, scale) = self.factors(&fixed);
        let ln_phi: Vec<Vec<f64>> = phi
            .iter()
            .map(|r| r.iter().map(|x| x.ln()).collect())
            .collect();
        let mut best: Option<(f64, Vec<u32>)> = None;
        for t in 0..self.trees.len() {
            let (value, labels) = self.max_product(t, &ln_phi);
            let value = value + scale - self.log_z[t];
            if value > best.as_ref().map_or(NEG_INF, |b| b.0) {
                best = Some((value, labels));
            }
        }
        let Some((value, assignment)) = best else {
            return Err(EvidenceError::ZeroLikelihood.into());
        };
        let full: Vec<Option<ClassId>> = assignment.iter().map(|&k| Some(k as ClassId)).collect();
        let log_max_product = value - (self.trees.len() as f64).ln();
        // The labelling's value sums the best forest's term and the others', so it is
        // never below it; the two are computed differently (log-space max-product,
        // scaled linear sums), and rounding put it up to 1e-7 below at 100,000 places:
        // the bound is kept.
        let log_probability = self.mix(&self.tree_values(&full).0)?.max(log_max_product);
        Ok(Mpe {
            assignment,
            log_max_product,
            log_probability,
        })
    }

    /// Max-product in forest `t` (log space): the best unnormalised log value and its
    /// labelling (ties to the smallest class).
    fn max_product(&self, t: usize, ln_phi: &[Vec<f64>]) -> (f64, Vec<u32>) {
        let forest = &self.trees.forests[t];
        let c = self.classes;
        let n = self.num_places();
        let mut lmsg = vec![Vec::new(); n];
        let mut arg: Vec<Vec<u32>> = vec![Vec::new(); n];
        let mut root_best = vec![0u32; n];
        let mut total = 0.0;
        for &v in forest.order.iter().rev() {
            let v = v as usize;
            let mut lb = ln_phi[v].clone();
            for &ch in &self.children[t][v] {
                for (x, m) in lb.iter_mut().zip(&lmsg[ch as usize]) {
                    *x += m;
                }
            }
            if forest.parent[v] != NO_PARENT {
                let mut m = vec![NEG_INF; c];
                let mut a_of = vec![0u32; c];
                for a in 0..c {
                    for (b, &x) in lb.iter().enumerate() {
                        let y = self.ln_psi[a * c + b] + x;
                        if y > m[a] {
                            m[a] = y;
                            a_of[a] = b as u32;
                        }
                    }
                }
                lmsg[v] = m;
                arg[v] = a_of;
            } else {
                let (k, &m) = lb.iter().enumerate().fold((0, &NEG_INF), |acc, (k, x)| {
                    if *x > *acc.1 { (k, x) } else { acc }
                });
                root_best[v] = k as u32;
                total += m;
            }
        }
        let mut labels = vec![0u32; n];
        for &v in &forest.order {
            let v = v as usize;
            let p = forest.parent[v];
            labels[v] = if p == NO_PARENT {
                root_best[v]
            } else {
                arg[v][labels[p as usize] as usize]
            };
        }
        (total, labels)
    }
}

/// `ln Σ exp(x)` (max-shifted; `-∞` when every entry is).
fn log_sum_exp(x: &[f64]) -> f64 {
    let m = x.iter().cloned().fold(NEG_INF, f64::max);
    if m == NEG_INF {
        return NEG_INF;
    }
    m + x.iter().map(|v| (v - m).exp()).sum::<f64>().ln()
}
