//! Component-wise exact evaluation of an instance GraphSPN, with incremental updates.
//!
//! The instance SPN of [`super::Instance`] stores one copy of a template SPN per
//! component, so its size is (places × template size): about 0.5 MB per place with
//! the demo model. [`ComponentInstance`] answers the same queries without building it:
//! the root mixes D decompositions with weight 1/D, each decomposition is a product of
//! components, and each component is its template's network evaluated on the
//! component's places (template node order). One evaluation plan per template is
//! shared by every component, so memory is `O(places × D × classes)` (evidence, one
//! cached log-value and one row of local posteriors per component place) plus
//! `O(template size)` scratch per thread; time is linear in places.
//!
//! Numerics are the interpreter's: natural logs in `f64`, max-shifted log-sum-exp at
//! sums, flows `f(child) = f(n)·exp(ln w + ln v(child) − ln v(n))` downwards, so
//! evidence as small as `1e-300` per place never underflows. Results agree with
//! [`super::InstanceModel`] (the explicit reference) to a few ulps per node on the
//! paths involved (tested to 1e-9).
//!
//! # Incremental updates
//!
//! The state caches, per distinct component, its log-value and (once asked for) its
//! local posteriors, and per decomposition its log-value as the root of a binary tree
//! of partial sums over its components' cached log-values. [`ComponentInstance::set_evidence`]
//! and [`ComponentInstance::clear_evidence`] re-evaluate only the components containing
//! the place (at most one per decomposition) and recompute `O(log components)` partial
//! sums in each decomposition using them; nothing is ever subtracted, so a state after
//! any number of updates holds exactly (bit for bit) the values a fresh evaluation of
//! the same evidence gives. Costs after one update:
//!
//! - the update itself: ≤ D template upward passes (`O(D × template edges)`);
//! - [`ComponentInstance::log_likelihood`] from the cache: `O(D)`;
//! - [`ComponentInstance::marginal`] of one place: ≤ D template downward passes, `O(D × classes)` mix;
//! - [`ComponentInstance::marginals`] of every place: ≤ D downward passes plus the
//!   `O(places × D × classes)` mix;
//! - [`ComponentInstance::mpe`] and [`ComponentInstance::log_likelihood_labelled`]:
//!   a full pass (max-product or clamped evaluation is not cached).
//!
//! [`ComponentInstance::grow`] follows a growing map the way [`super::Instance::grow`]
//! does (same decompositions): components that are still used keep their cached values;
//! only new components are evaluated.

use std::collections::{BTreeSet, HashMap};

use graphspn_runtime::EvidenceError;
use rayon::prelude::*;

use super::build::edge_set;
use super::grow::grow_decompositions;
use super::{CopyStats, InstanceError, InstanceParams, InstanceQueryError};
use crate::decompose::{Component, Decomposition};
use crate::inputs::check_inputs;
use crate::interpreter::{Marginals, Mpe};
use crate::learn::Model;
use crate::map::{ClassId, TopoMap};
use crate::spn::{Mixing, Node};

mod plan;
mod queries;

use plan::{Blank, NEG_INF, Plan, Scratch, SumTree};

/// An instance GraphSPN evaluated component by component against the model's shared
/// template networks, with a cached state for incremental evidence updates (see the
/// module documentation for what each call costs).
///
/// Evidence is one row of class likelihoods α ≥ 0 per place; a place without evidence
/// has α = 1 for every class (so [`ComponentInstance::log_likelihood`] is
/// `ln P(evidence of the observed places)`, as `graphspn infer` reports it).
#[derive(Clone, Debug)]
pub struct ComponentInstance {
    num_classes: usize,
    num_places: usize,
    /// User-facing place ids, for error messages.
    place_ids: Vec<u64>,
    plans: Vec<Plan>,
    decompositions: Vec<Decomposition>,
    edges: BTreeSet<(usize, usize)>,
    /// Distinct components: template, and places at `comp_start[i]..comp_start[i+1]`.
    comp_template: Vec<u32>,
    comp_start: Vec<usize>,
    comp_places: Vec<u32>,
    /// Components of each decomposition (indices into the distinct components).
    dec_comps: Vec<Vec<u32>>,
    /// Uses of component `i` as (decomposition, position): `uses[uses_start[i]..uses_start[i+1]]`.
    uses_start: Vec<u32>,
    uses: Vec<(u32, u32)>,
    /// `place_comp[d·n + p]`: component of place `p` in decomposition `d`, and
    /// `place_pos[d·n + p]` its variable within it.
    place_comp: Vec<u32>,
    place_pos: Vec<u32>,
    /// `ln α` of every place, `p·C + c`.
    log_alpha: Vec<f64>,
    /// Whether place `p` has evidence other than all ones.
    observed: Vec<bool>,
    /// Per template, its value, max-product value and local posteriors with no
    /// evidence (shared by every component whose places are all unobserved).
    blank: Vec<Blank>,
    /// Cached log-value of each component, valid where `ll_valid[i]`.
    comp_ll: Vec<f64>,
    ll_valid: Vec<bool>,
    /// The decomposition sums must be rebuilt from `comp_ll`.
    trees_stale: bool,
    /// Cached local posteriors of each component (its places × classes, at
    /// `comp_start[i]·C`), valid where `post_valid[i]`.
    comp_post: Vec<f64>,
    post_valid: Vec<bool>,
    /// Log-value of each decomposition's product.
    dec_tree: Vec<SumTree>,
    scratch: Scratch,
    last_stats: CopyStats,
}

/// Bytes the component evaluator is estimated to need for a map of `places` places,
/// `classes` classes and `decompositions` decompositions chosen among `candidates`
/// random partitions (an upper bound of the state, its index and the decomposition
/// step's temporaries, within a factor of about 2; the template plans and the map
/// itself are not included).
pub fn estimated_component_bytes(
    places: usize,
    classes: usize,
    decompositions: usize,
    candidates: usize,
) -> u128 {
    let (n, c, d, k) = (
        places as u128,
        classes as u128,
        decompositions as u128,
        candidates as u128,
    );
    // Evidence; per (place, decomposition): posterior row, index, component places,
    // the decomposition's copy and per-component overhead; candidates: a used flag and a
    // component list per place.
    n * c * 8 + n * d * (c * 8 + 8 + 4 + 8 + 96) + n * k * 64
}

impl ComponentInstance {
    /// Decomposes `map` ([`InstanceParams::decompose`]: the decompositions of
    /// [`super::Instance::for_map`]) and prepares the evaluator with no evidence.
    pub fn for_map(
        model: &Model,
        map: &TopoMap,
        params: &InstanceParams,
    ) -> Result<Self, InstanceQueryError> {
        let decompositions = params.decompose(model, map)?;
        Self::build(model, map, decompositions)
    }

    /// Prepares the evaluator of the instance of `map` mixing `decompositions` (the
    /// same checks as [`super::Instance::build`], and every template SPN is validated),
    /// with no evidence. `O(places × D × template size)` time.
    pub fn build(
        model: &Model,
        map: &TopoMap,
        decompositions: Vec<Decomposition>,
    ) -> Result<Self, InstanceQueryError> {
        check_inputs(model, map, &decompositions).map_err(InstanceError::from)?;
        let num_classes = model.classes.len();
        let mut plans = Vec::with_capacity(model.spns.len());
        for (t, spn) in model.templates.iter().zip(&model.spns) {
            spn.validate()
                .map_err(|source| InstanceQueryError::InvalidTemplateSpn {
                    template: t.name.clone(),
                    source,
                })?;
            plans.push(Plan::new(spn, num_classes));
        }
        let mut inst = ComponentInstance {
            num_classes,
            num_places: map.num_places(),
            place_ids: map.places().map(|p| u64::from(p.id)).collect(),
            plans,
            decompositions: Vec::new(),
            edges: edge_set(map),
            comp_template: Vec::new(),
            comp_start: vec![0],
            comp_places: Vec::new(),
            dec_comps: Vec::new(),
            uses_start: Vec::new(),
            uses: Vec::new(),
            place_comp: Vec::new(),
            place_pos: Vec::new(),
            log_alpha: vec![0.0; map.num_places() * num_classes],
            observed: vec![false; map.num_places()],
            blank: Vec::new(),
            comp_ll: Vec::new(),
            ll_valid: Vec::new(),
            trees_stale: true,
            comp_post: Vec::new(),
            post_valid: Vec::new(),
            dec_tree: Vec::new(),
            scratch: Scratch::default(),
            last_stats: CopyStats::default(),
        };
        inst.blank = inst
            .plans
            .iter()
            .zip(&model.templates)
            .map(|(plan, t)| Blank::new(plan, t.num_nodes, num_classes))
            .collect();
        inst.index(decompositions, None);
        Ok(inst)
    }

    /// Number of places.
    pub fn num_places(&self) -> usize {
        self.num_places
    }

    /// Number of classes per place.
    pub fn num_classes(&self) -> usize {
        self.num_classes
    }

    /// Number of distinct components (one per template copy of the explicit instance).
    pub fn num_components(&self) -> usize {
        self.comp_template.len()
    }

    /// The decompositions mixed, in root-child order.
    pub fn decompositions(&self) -> &[Decomposition] {
        &self.decompositions
    }

    /// Distinct components reused (cached values kept) and evaluated by the last
    /// [`ComponentInstance::build`] / [`ComponentInstance::grow`] / [`ComponentInstance::update`].
    pub fn last_copy_stats(&self) -> CopyStats {
        self.last_stats
    }

    /// Bytes held by the state and its index (capacity of every buffer, excluding the
    /// decompositions' own component lists and the template plans).
    pub fn state_bytes(&self) -> usize {
        fn b<T>(v: &Vec<T>) -> usize {
            v.capacity() * std::mem::size_of::<T>()
        }
        b(&self.place_ids)
            + b(&self.comp_template)
            + b(&self.comp_start)
            + b(&self.comp_places)
            + self.dec_comps.iter().map(b).sum::<usize>()
            + b(&self.uses_start)
            + b(&self.uses)
            + b(&self.place_comp)
            + b(&self.place_pos)
            + b(&self.log_alpha)
            + b(&self.comp_ll)
            + b(&self.observed)
            + b(&self.ll_valid)
            + b(&self.comp_post)
            + b(&self.post_valid)
            + self.dec_tree.iter().map(|t| b(&t.t)).sum::<usize>()
    }

    /// Rebuilds the component index for `decompositions` (already checked). Components
    /// found in `old` (the previous distinct components and their caches) keep their
    /// cached values; the others are evaluated (in parallel).
    fn index(&mut self, decompositions: Vec<Decomposition>, old: Option<OldCache>) {
        let n = self.num_places;
        let c = self.num_classes;
        let d_count = decompositions.len();
        let mut ids: HashMap<&Component, u32> = HashMap::new();
        let mut comp_template = Vec::new();
        let mut comp_start = vec![0usize];
        let mut comp_places: Vec<u32> = Vec::new();
        let mut dec_comps = Vec::with_capacity(d_count);
        let mut place_comp = vec![0u32; d_count * n];
        let mut place_pos = vec![0u32; d_count * n];
        let mut use_count: Vec<u32> = Vec::new();
        for (d, dec) in decompositions.iter().enumerate() {
            let mut list = Vec::with_capacity(dec.components.len());
            for comp in &dec.components {
                let id = *ids.entry(comp).or_insert_with(|| {
                    comp_template.push(comp.template as u32);
                    comp_places.extend(comp.places.iter().map(|&p| p as u32));
                    comp_start.push(comp_places.len());
                    use_count.push(0);
                    (comp_template.len() - 1) as u32
                });
                use_count[id as usize] += 1;
                for (v, &p) in comp.places.iter().enumerate() {
                    place_comp[d * n + p] = id;
                    place_pos[d * n + p] = v as u32;
                }
                list.push(id);
            }
            dec_comps.push(list);
        }
        drop(ids);
        let m = comp_template.len();
        let mut uses_start = Vec::with_capacity(m + 1);
        let mut total = 0u32;
        for &k in &use_count {
            uses_start.push(total);
            total += k;
        }
        uses_start.push(total);
        let mut uses = vec![(0u32, 0u32); total as usize];
        let mut fill: Vec<u32> = uses_start[..m].to_vec();
        for (d, list) in dec_comps.iter().enumerate() {
            for (k, &id) in list.iter().enumerate() {
                uses[fill[id as usize] as usize] = (d as u32, k as u32);
                fill[id as usize] += 1;
            }
        }
        drop(fill);
        self.comp_template = comp_template;
        self.comp_start = comp_start;
        self.comp_places = comp_places;
        self.dec_comps = dec_comps;
        self.uses_start = uses_start;
        self.uses = uses;
        self.place_comp = place_comp;
        self.place_pos = place_pos;
        self.comp_ll = vec![0.0; m];
        self.ll_valid = vec![false; m];
        self.comp_post = vec![0.0; self.comp_places.len() * c];
        self.post_valid = vec![false; m];
        let mut stats = CopyStats::default();
        if let Some(old) = old {
            for i in 0..m {
                let key = (self.comp_template[i], self.places_of(i).to_vec());
                if let Some(&j) = old.ids.get(&key) {
                    let j = j as usize;
                    stats.reused += 1;
                    self.comp_ll[i] = old.comp_ll[j];
                    self.ll_valid[i] = old.ll_valid[j];
                    if old.post_valid[j] {
                        let (a, b) = (self.comp_start[i] * c, self.comp_start[i + 1] * c);
                        let (oa, ob) = (old.comp_start[j] * c, old.comp_start[j + 1] * c);
                        self.comp_post[a..b].copy_from_slice(&old.comp_post[oa..ob]);
                        self.post_valid[i] = true;
                    }
                }
            }
        }
        stats.built = m - stats.reused;
        self.decompositions = decompositions;
        self.last_stats = stats;
        self.trees_stale = true;
    }

    /// Places of distinct component `i`, in template variable order.
    fn places_of(&self, i: usize) -> &[u32] {
        &self.comp_places[self.comp_start[i]..self.comp_start[i + 1]]
    }

    /// Computes (in parallel) the log-value of every component with a stale cache,
    /// then rebuilds the decomposition sums if anything changed.
    fn refresh_values(&mut self) {
        let c = self.num_classes;
        let (plans, comp_template, comp_start, comp_places, log_alpha, observed, blank) = (
            &self.plans,
            &self.comp_template,
            &self.comp_start,
            &self.comp_places,
            &self.log_alpha,
            &self.observed,
            &self.blank,
        );
        self.comp_ll
            .par_iter_mut()
            .zip(self.ll_valid.par_iter_mut())
            .enumerate()
            .filter(|(_, (_, valid))| !**valid)
            .for_each_init(Scratch::default, |s, (i, (ll, valid))| {
                let places = &comp_places[comp_start[i]..comp_start[i + 1]];
                let t = comp_template[i] as usize;
                *ll = if places.iter().all(|&p| !observed[p as usize]) {
                    blank[t].ll
                } else {
                    fill_slots(&mut s.slots, places, log_alpha, c, None);
                    plans[t].up(s, false)
                };
                *valid = true;
            });
        if self.trees_stale {
            self.rebuild_trees();
            self.trees_stale = false;
        }
    }

    fn rebuild_trees(&mut self) {
        self.dec_tree = self
            .dec_comps
            .iter()
            .map(|list| SumTree::new(list.iter().map(|&i| self.comp_ll[i as usize])))
            .collect();
    }

    /// Computes the local posteriors of every component with a stale cache (in parallel).
    fn refresh_posteriors(&mut self) {
        let c = self.num_classes;
        let (plans, comp_template, comp_start, comp_places, log_alpha, observed, blank) = (
            &self.plans,
            &self.comp_template,
            &self.comp_start,
            &self.comp_places,
            &self.log_alpha,
            &self.observed,
            &self.blank,
        );
        let mut slices: Vec<(usize, &mut [f64], &mut f64, &mut bool)> = Vec::new();
        let mut rest = &mut self.comp_post[..];
        for (i, (ll, valid)) in self.comp_ll.iter_mut().zip(&mut self.ll_valid).enumerate() {
            let len = (comp_start[i + 1] - comp_start[i]) * c;
            let (a, b) = rest.split_at_mut(len);
            rest = b;
            if !self.post_valid[i] {
                slices.push((i, a, ll, valid));
            }
        }
        slices
            .into_par_iter()
            .for_each_init(Scratch::default, |s, (i, out, ll, valid)| {
                let places = &comp_places[comp_start[i]..comp_start[i + 1]];
                let t = comp_template[i] as usize;
                if places.iter().all(|&p| !observed[p as usize]) {
                    *ll = blank[t].ll;
                    out.copy_from_slice(&blank[t].post);
                } else {
                    fill_slots(&mut s.slots, places, log_alpha, c, None);
                    let plan = &plans[t];
                    *ll = plan.up(s, false);
                    plan.down(s, c, out);
                }
                *valid = true;
            });
        self.post_valid.iter_mut().for_each(|v| *v = true);
    }

    /// Re-evaluates component `i` after its evidence changed (value now, posteriors stale).
    fn reevaluate(&mut self, i: usize) {
        let c = self.num_classes;
        let places = &self.comp_places[self.comp_start[i]..self.comp_start[i + 1]];
        fill_slots(&mut self.scratch.slots, places, &self.log_alpha, c, None);
        let ll = self.plans[self.comp_template[i] as usize].up(&mut self.scratch, false);
        self.comp_ll[i] = ll;
        self.ll_valid[i] = true;
        self.post_valid[i] = false;
        if self.trees_stale {
            // Rebuilt from every cached value at the next query.
            return;
        }
        for u in self.uses_start[i]..self.uses_start[i + 1] {
            let (d, k) = self.uses[u as usize];
            self.dec_tree[d as usize].set(k as usize, ll);
        }
    }

    /// The distinct components containing `place` (one per decomposition, shared ones once).
    fn components_of(&self, place: usize) -> Vec<usize> {
        let n = self.num_places;
        let mut out: Vec<usize> = (0..self.dec_comps.len())
            .map(|d| self.place_comp[d * n + place] as usize)
            .collect();
        out.sort_unstable();
        out.dedup();
        out
    }

    fn check_place(&self, place: usize) -> Result<(), InstanceQueryError> {
        if place >= self.num_places {
            return Err(InstanceQueryError::PlaceOutOfRange {
                place,
                count: self.num_places,
            });
        }
        Ok(())
    }

    /// Checks one evidence row of place index `place` (the interpreter's rules,
    /// [`crate::interpreter::check_row`]).
    fn check_row(&self, place: usize, row: &[f64]) -> Result<(), InstanceQueryError> {
        crate::interpreter::check_row(place, self.place_ids[place], row, self.num_classes)
            .map_err(|e| InstanceQueryError::Inference(e.into()))
    }

    /// Sets the evidence of every place (one row per place, place order) and
    /// re-evaluates every component: a full pass, `O(places × D × template size)`.
    pub fn set_all_evidence(&mut self, rows: &[Vec<f64>]) -> Result<(), InstanceQueryError> {
        if rows.len() != self.num_places {
            return Err(InstanceQueryError::Inference(
                EvidenceError::WrongLength {
                    expected: self.num_places,
                    found: rows.len(),
                }
                .into(),
            ));
        }
        for (p, row) in rows.iter().enumerate() {
            self.check_row(p, row)?;
        }
        let c = self.num_classes;
        for (p, row) in rows.iter().enumerate() {
            for (k, &a) in row.iter().enumerate() {
                self.log_alpha[p * c + k] = a.ln();
            }
            self.observed[p] = row.iter().any(|&a| a != 1.0);
        }
        // Evaluated lazily by the next query (values only, or with posteriors).
        self.ll_valid.iter_mut().for_each(|v| *v = false);
        self.post_valid.iter_mut().for_each(|v| *v = false);
        self.trees_stale = true;
        Ok(())
    }

    /// Sets the evidence row (α per class) of place index `place`; re-evaluates only
    /// the components containing it (≤ D template upward passes). Invalid rows are
    /// rejected with the interpreter's [`EvidenceError`] rules and change nothing.
    pub fn set_evidence(&mut self, place: usize, row: &[f64]) -> Result<(), InstanceQueryError> {
        self.check_place(place)?;
        self.check_row(place, row)?;
        let c = self.num_classes;
        for (k, &a) in row.iter().enumerate() {
            self.log_alpha[place * c + k] = a.ln();
        }
        self.observed[place] = row.iter().any(|&a| a != 1.0);
        for i in self.components_of(place) {
            self.reevaluate(i);
        }
        Ok(())
    }

    /// Removes the evidence of place index `place` (α = 1 for every class), at the
    /// cost of [`ComponentInstance::set_evidence`].
    pub fn clear_evidence(&mut self, place: usize) -> Result<(), InstanceQueryError> {
        self.check_place(place)?;
        let ones = vec![1.0; self.num_classes];
        self.set_evidence(place, &ones)
    }

    /// Follows `grown_map` (grown from the map of the current state: places appended,
    /// edges added) with the decompositions [`super::Instance::grow`] would make for the
    /// same seed ([`grow_decompositions`]); components still used keep their cached
    /// values, only new ones are evaluated. New places have no evidence; old places keep
    /// theirs. Returns how many distinct components were reused and evaluated.
    pub fn grow(
        &mut self,
        model: &Model,
        grown_map: &TopoMap,
        seed: u64,
    ) -> Result<CopyStats, InstanceQueryError> {
        let decompositions = grow_decompositions(
            &self.decompositions,
            self.num_places,
            &self.edges,
            grown_map,
            &model.templates,
            seed,
        )?;
        self.update(model, grown_map, decompositions)?;
        Ok(self.last_stats)
    }

    /// Replaces the decompositions after the map grew (existing place indices
    /// unchanged), keeping the cached values of every component still used. `model`
    /// must be the model the state was built with (its templates are checked against
    /// the decompositions; the template networks of the build are kept).
    pub fn update(
        &mut self,
        model: &Model,
        map: &TopoMap,
        decompositions: Vec<Decomposition>,
    ) -> Result<(), InstanceQueryError> {
        check_inputs(model, map, &decompositions).map_err(InstanceError::from)?;
        let n = map.num_places();
        if n < self.num_places {
            return Err(InstanceError::MapShrank {
                before: self.num_places,
                after: n,
            }
            .into());
        }
        let c = self.num_classes;
        let m = self.num_components();
        let mut ids = HashMap::with_capacity(m);
        for i in 0..m {
            ids.insert(
                (self.comp_template[i], self.places_of(i).to_vec()),
                i as u32,
            );
        }
        let old = OldCache {
            ids,
            comp_start: std::mem::take(&mut self.comp_start),
            comp_ll: std::mem::take(&mut self.comp_ll),
            ll_valid: std::mem::take(&mut self.ll_valid),
            comp_post: std::mem::take(&mut self.comp_post),
            post_valid: std::mem::take(&mut self.post_valid),
        };
        self.log_alpha.resize(n * c, 0.0);
        self.observed.resize(n, false);
        self.place_ids = map.places().map(|p| u64::from(p.id)).collect();
        self.num_places = n;
        self.edges = edge_set(map);
        self.index(decompositions, Some(old));
        Ok(())
    }
}

/// Caches of the components before an update, by (template, places).
struct OldCache {
    ids: HashMap<(u32, Vec<u32>), u32>,
    comp_start: Vec<usize>,
    comp_ll: Vec<f64>,
    ll_valid: Vec<bool>,
    comp_post: Vec<f64>,
    post_valid: Vec<bool>,
}

/// Gathers the leaf log-values of a component: `ln α` of its places, `-∞` for a class
/// excluded by `fixed`.
fn fill_slots(
    slots: &mut Vec<f64>,
    places: &[u32],
    log_alpha: &[f64],
    c: usize,
    fixed: Option<&[Option<u32>]>,
) {
    slots.clear();
    for &p in places {
        let p = p as usize;
        let row = &log_alpha[p * c..p * c + c];
        match fixed.and_then(|f| f[p]) {
            None => slots.extend_from_slice(row),
            Some(k) => slots.extend(
                row.iter()
                    .enumerate()
                    .map(|(j, &a)| if j == k as usize { a } else { NEG_INF }),
            ),
        }
    }
}

/// `ln Σ exp(v)`, max-shifted; `-∞` for an empty slice or all `-∞`.
fn log_sum_exp(v: &[f64]) -> f64 {
    let m = v.iter().copied().fold(NEG_INF, f64::max);
    if m == NEG_INF {
        return NEG_INF;
    }
    m + v.iter().map(|&x| (x - m).exp()).sum::<f64>().ln()
}

/// Bytes the explicit instance SPN ([`super::Instance::build`]) of `decompositions`
/// is estimated to take: every distinct component copies its template's nodes (an
/// [`Node`] each, 4 bytes per child, 8 per sum weight, allocation overhead), plus
/// leaves, products and the root. Within a factor of about 1.5 of the measured heap.
pub fn estimated_explicit_bytes(model: &Model, decompositions: &[Decomposition]) -> u128 {
    let per_template: Vec<u128> = model
        .spns
        .iter()
        .map(|spn| {
            let node = std::mem::size_of::<Node>() as u128;
            spn.nodes
                .iter()
                .map(|n| match n {
                    Node::Leaf { .. } => 0,
                    Node::Sum { children, .. } => node + 32 + children.len() as u128 * 12,
                    Node::Product { children } => node + 16 + children.len() as u128 * 4,
                })
                .sum()
        })
        .collect();
    let mut seen: BTreeSet<&Component> = BTreeSet::new();
    let mut total: u128 = 0;
    for d in decompositions {
        for comp in &d.components {
            if seen.insert(comp) {
                total += per_template.get(comp.template).copied().unwrap_or(0) + 64;
            }
            total += 4;
        }
        total += 64;
    }
    let places = decompositions.first().map_or(0, |d| {
        d.components.iter().map(|c| c.places.len()).sum::<usize>()
    });
    total + (places * model.classes.len()) as u128 * (std::mem::size_of::<Node>() as u128 + 8)
}
