//! The queries of a [`ComponentInstance`]: log-likelihood, marginals (all places or
//! one), the labelled log-likelihood and MPE, from the cached component values.

use super::*;

impl ComponentInstance {
    /// Decomposition log-values and `ln Σ_d exp(·)`; errors when every one is `-∞`.
    pub(super) fn mix(&mut self) -> Result<(Vec<f64>, f64), InstanceQueryError> {
        self.refresh_values();
        let vals: Vec<f64> = self.dec_tree.iter().map(SumTree::total).collect();
        let lse = log_sum_exp(&vals);
        if lse == NEG_INF {
            return Err(InstanceQueryError::Inference(
                EvidenceError::ZeroLikelihood.into(),
            ));
        }
        Ok((vals, lse))
    }

    /// `ln P(evidence)` from the cache, `O(D)`: `ln(1/D) + ln Σ_d exp(ln v_d)`.
    /// Errors with [`EvidenceError::ZeroLikelihood`] when the evidence has probability 0.
    pub fn log_likelihood(&mut self) -> Result<f64, InstanceQueryError> {
        let (_, lse) = self.mix()?;
        Ok(lse - (self.dec_comps.len() as f64).ln())
    }

    /// Posterior weight of each decomposition, `P(d | evidence)`.
    pub(super) fn dec_weights(&mut self) -> Result<Vec<f64>, InstanceQueryError> {
        let (vals, lse) = self.mix()?;
        Ok(vals.iter().map(|&v| (v - lse).exp()).collect())
    }

    /// `P(Y_p = c | evidence)` for every place and class, and `ln P(evidence)`:
    /// stale component posteriors are recomputed (all of them after
    /// [`ComponentInstance::set_all_evidence`], ≤ D after one update), then mixed by
    /// decomposition posterior, `O(places × D × classes)`. Rows are renormalised.
    pub fn marginals(&mut self) -> Result<Marginals, InstanceQueryError> {
        self.refresh_posteriors();
        let w = self.dec_weights()?;
        let n = self.num_places;
        let probs = (0..n).map(|p| self.mixed_row(p, &w)).collect();
        Ok(Marginals {
            log_likelihood: self.log_likelihood()?,
            probs,
        })
    }

    /// Per-place class probabilities mixed as `mixing` says, and `ln P(evidence)`:
    /// [`Mixing::Posterior`] is [`ComponentInstance::marginals`] (the exact
    /// marginals of the mixture); [`Mixing::Average`] gives every decomposition the
    /// same weight `1/D` (the mean of the D decompositions' exact marginals, an
    /// ensemble rather than the mixture's posterior). Same costs as `marginals`.
    pub fn marginals_mixed(&mut self, mixing: Mixing) -> Result<Marginals, InstanceQueryError> {
        match mixing {
            Mixing::Posterior => self.marginals(),
            Mixing::Average => {
                self.refresh_posteriors();
                // Errors as `marginals` does when the evidence has probability 0.
                let log_likelihood = self.log_likelihood()?;
                let d = self.dec_comps.len();
                let w = vec![1.0 / d as f64; d];
                let probs = (0..self.num_places)
                    .map(|p| self.mixed_row(p, &w))
                    .collect();
                Ok(Marginals {
                    log_likelihood,
                    probs,
                })
            }
        }
    }

    /// `P(Y_place = c | evidence)` for one place index: ≤ D component downward passes
    /// (only stale ones) and an `O(D × classes)` mix.
    pub fn marginal(&mut self, place: usize) -> Result<Vec<f64>, InstanceQueryError> {
        self.check_place(place)?;
        let w = self.dec_weights()?;
        let c = self.num_classes;
        for i in self.components_of(place) {
            if !self.post_valid[i] {
                let places = &self.comp_places[self.comp_start[i]..self.comp_start[i + 1]];
                fill_slots(&mut self.scratch.slots, places, &self.log_alpha, c, None);
                let plan = &self.plans[self.comp_template[i] as usize];
                plan.up(&mut self.scratch, false);
                let out = &mut self.comp_post[self.comp_start[i] * c..self.comp_start[i + 1] * c];
                plan.down(&mut self.scratch, c, out);
                self.post_valid[i] = true;
            }
        }
        Ok(self.mixed_row(place, &w))
    }

    /// `Σ_d w_d · post_d(place)` (posteriors of the components involved must be fresh).
    pub(super) fn mixed_row(&self, place: usize, w: &[f64]) -> Vec<f64> {
        let (n, c) = (self.num_places, self.num_classes);
        let mut row = vec![0.0; c];
        for (d, &wd) in w.iter().enumerate() {
            if wd == 0.0 {
                continue;
            }
            let i = self.place_comp[d * n + place] as usize;
            let at = (self.comp_start[i] + self.place_pos[d * n + place] as usize) * c;
            for (r, &q) in row.iter_mut().zip(&self.comp_post[at..at + c]) {
                *r += wd * q;
            }
        }
        let total: f64 = row.iter().sum();
        if total > 0.0 {
            row.iter_mut().for_each(|x| *x /= total);
        }
        row
    }

    pub(super) fn fixed(
        &self,
        labels: &[Option<ClassId>],
    ) -> Result<Vec<Option<u32>>, InstanceQueryError> {
        let n = self.num_places;
        if labels.is_empty() {
            return Ok(vec![None; n]);
        }
        if labels.len() != n {
            return Err(InstanceQueryError::BadLabels(format!(
                "{} labels for {n} places",
                labels.len()
            )));
        }
        let c = self.num_classes;
        if let Some(p) = labels
            .iter()
            .position(|l| l.is_some_and(|l| l as usize >= c))
        {
            return Err(InstanceQueryError::BadLabels(format!(
                "place index {p}: class {} out of range ({c} classes)",
                labels[p].unwrap_or_default()
            )));
        }
        Ok(labels.iter().map(|l| l.map(u32::from)).collect())
    }

    /// Every component's log-value (sum-product, or max-product with `max`) under the
    /// current evidence with `fixed` places clamped: one full parallel pass.
    pub(super) fn pass(&self, fixed: &[Option<u32>], max: bool) -> Vec<f64> {
        let c = self.num_classes;
        (0..self.num_components())
            .into_par_iter()
            .map_init(Scratch::default, |s, i| {
                let places = self.places_of(i);
                let t = self.comp_template[i] as usize;
                if places
                    .iter()
                    .all(|&p| !self.observed[p as usize] && fixed[p as usize].is_none())
                {
                    return if max {
                        self.blank[t].max
                    } else {
                        self.blank[t].ll
                    };
                }
                fill_slots(&mut s.slots, places, &self.log_alpha, c, Some(fixed));
                self.plans[t].up(s, max)
            })
            .collect()
    }

    /// `ln(1/D) + ln Σ_d exp(Σ_{i ∈ d} value_i)` (log-sum-exp, or max with `max`) and
    /// the best decomposition (ties: the lowest).
    pub(super) fn root(&self, values: &[f64], max: bool) -> (f64, usize) {
        let decs: Vec<f64> = self
            .dec_comps
            .iter()
            .map(|list| SumTree::new(list.iter().map(|&i| values[i as usize])).total())
            .collect();
        let ln_w = -(decs.len() as f64).ln();
        let mut best = 0;
        for (d, &v) in decs.iter().enumerate() {
            if v > decs[best] {
                best = d;
            }
        }
        let v = if max {
            decs[best] + ln_w
        } else {
            log_sum_exp(&decs) + ln_w
        };
        (v, best)
    }

    /// `ln P(Y_p = labels[p] for every labelled p, evidence)` (unlabelled places, `None`,
    /// are summed out; an empty slice = none labelled, answered from the cache in `O(D)`).
    /// With labels: one full clamped pass, `O(places × D × template size)`, not cached.
    pub fn log_likelihood_labelled(
        &mut self,
        labels: &[Option<ClassId>],
    ) -> Result<f64, InstanceQueryError> {
        let fixed = self.fixed(labels)?;
        if fixed.iter().all(Option::is_none) {
            return self.log_likelihood();
        }
        let (v, _) = self.root(&self.pass(&fixed, false), false);
        if v == NEG_INF {
            return Err(InstanceQueryError::Inference(
                EvidenceError::ZeroLikelihood.into(),
            ));
        }
        Ok(v)
    }

    /// Max-product labelling (as [`crate::instance::InstanceModel::mpe`]): the best decomposition's
    /// best induced tree, each component backtracked in its template. Costs one full
    /// max-product pass, the backtracking of one decomposition's components and one full
    /// clamped pass for `log_probability`.
    pub fn mpe(&mut self, labels: &[Option<ClassId>]) -> Result<Mpe, InstanceQueryError> {
        let fixed = self.fixed(labels)?;
        let values = self.pass(&fixed, true);
        let (log_max_product, best) = self.root(&values, true);
        if log_max_product == NEG_INF {
            return Err(InstanceQueryError::Inference(
                EvidenceError::ZeroLikelihood.into(),
            ));
        }
        let c = self.num_classes;
        let mut assignment = vec![0u32; self.num_places];
        let mut local = Vec::new();
        for &i in &self.dec_comps[best] {
            let i = i as usize;
            let places = &self.comp_places[self.comp_start[i]..self.comp_start[i + 1]];
            fill_slots(
                &mut self.scratch.slots,
                places,
                &self.log_alpha,
                c,
                Some(&fixed),
            );
            let plan = &self.plans[self.comp_template[i] as usize];
            plan.up(&mut self.scratch, true);
            local.clear();
            local.resize(places.len(), 0u32);
            plan.backtrack(&mut self.scratch, c, &mut local);
            for (&p, &k) in places.iter().zip(&local) {
                assignment[p as usize] = k;
            }
        }
        let full: Vec<Option<u32>> = assignment.iter().map(|&k| Some(k)).collect();
        let (log_probability, _) = self.root(&self.pass(&full, false), false);
        if log_probability == NEG_INF {
            return Err(InstanceQueryError::Inference(
                EvidenceError::ZeroLikelihood.into(),
            ));
        }
        Ok(Mpe {
            assignment,
            log_max_product,
            log_probability,
        })
    }
}
