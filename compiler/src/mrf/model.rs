//! The paper's MRF baselines on a topological map.
//!
//! Both models have one variable `Y_i` per place (node index = place order) with
//! `C` states, and a unary factor `φ_i(c) = α_i^c` (the local evidence row).
//!
//! - [`Mrf2`]: one pairwise factor `ψ(Y_a, Y_b)` on every undirected edge.
//! - [`Mrf3`]: one three-variable factor `ψ(Y_A, Y_P, Y_B)` on every *connected
//!   triple*: every path `A–P–B`, i.e. every unordered pair `{A, B}` of
//!   neighbours of every pivot `P` (the paper's Three template, where `A` and `B`
//!   may also be adjacent). The factor's variable order is `[A, P, B]` with
//!   `A < B`; the potential is symmetric in `A ↔ B`, so the order of the two ends
//!   does not matter. **Triangles:** in a triangle `{X, Y, Z}` each of the three
//!   nodes is the pivot of one path, so the triangle yields three factors over
//!   the same variable set, each with a different variable in the pivot role.
//!   We keep all three: they are different relations ("X between Y and Z" is not
//!   "Y between X and Z"), this matches how training triples are counted (every
//!   path through every pivot), and it matches the paper's "three connected
//!   nodes in any configuration". COLD maps have many triangles (diagonal
//!   neighbours 1.13 m apart), so this does give those cliques more weight.
//!
//! # Potentials from co-occurrence counts
//!
//! Training counts every edge of every training map in both orientations
//! (a symmetric `C × C` table) and every path `A–P–B` in both orientations
//! `(A, P, B)` and `(B, P, A)` (a `C × C × C` table, symmetric in its ends).
//! Places without a ground-truth class are skipped. A pseudo-count is added to
//! every cell. With `p(·)` the resulting joint frequencies, the potential is
//! ([`Normalisation`]):
//!
//! - `Joint` (default): `ψ = p(a, b)` (or `p(a, p, b)`): plain co-occurrence
//!   frequencies.
//! - `Pmi`: `ψ(a, b) = p(a, b) / (p(a) p(b))` and
//!   `ψ(a, p, b) = p(a, p, b) / (p_A(a) p_P(p) p_B(b))`, with the marginals of
//!   the same table. Rationale: the paper's unary `α_i^c` is
//!   `P(Y_i = c, X_i = x_i)` and already contains the class prior. For a
//!   tree-shaped map the exact joint is
//!   `∏_i P(x_i | y_i) · ∏_edges p(a, b) / ∏_i p(y_i)^(d_i − 1)`, which equals
//!   `∏_i α_i(y_i) · ∏_edges p(a, b) / (p(a) p(b))`, so PMI-style potentials are
//!   the correct ones *on trees*; joint frequencies count the class prior once
//!   more per incident edge, which favours the dominant class (corridor).
//!
//! - `Normalised`: `ψ = p(a, b) / √(p(a) p(b))` (MRF-3: the joint over the
//!   square root of the product of its three marginals), halfway between the two.
//! - `Conditional`: `ψ(a, b) = p(b | a)` with `a` the factor's first variable,
//!   `ψ(a, p, b) = p(a, b | p)` given the pivot.
//!
//! Every potential is then raised to the *coupling* exponent
//! ([`CooccurrenceParams::coupling`]): 1 keeps it, values below 1 weaken the
//! dependencies (0 = independent places), above 1 strengthen them.
//!
//! Why `Joint` with coupling 1 is the default: it is the paper's baseline
//! ("paper-style"). Measured on COLD it is a weak one: it counts the class prior
//! again on every edge, so from NL3 on BP converges to the corridor everywhere;
//! PMI with coupling 1 instead lets the large self-affinity of rare classes
//! (`ψ(LO, LO) ≈ 35` vs `ψ(CR, CR) ≈ 2.7`) take over. The experiments choose
//! normalisation and coupling by validation on the training buildings
//! (`experiments::validate`); that tuned MRF is the baseline to beat.
//!
//! The default pseudo-count is 1 per cell (Laplace), which keeps every
//! potential positive, so an unseen class pair is unlikely but never impossible.

use super::MrfError;
use super::bp::{BpOptions, BpResult, loopy_bp};
use super::factor_graph::FactorGraph;
use crate::domain::{self, DomainError};
use crate::map::{ClassId, TopoMap};
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// How co-occurrence frequencies become potentials; see the module docs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Normalisation {
    /// Joint frequency divided by the product of its marginals (PMI-style ratio).
    Pmi,
    /// Joint frequency (the paper-style baseline).
    #[default]
    Joint,
    /// Joint frequency divided by the marginal of one variable: MRF-2
    /// `p(b | a)` with `a` the factor's first variable (lower place index),
    /// MRF-3 `p(a, b | p)` given the pivot.
    Conditional,
    /// Joint frequency divided by the square root of the product of its
    /// marginals: `p(a, b) / √(p(a) p(b))` (MRF-3: `p(a, p, b) / √(p_A p_P p_B)`),
    /// halfway between `Joint` and `Pmi`.
    Normalised,
}

impl Normalisation {
    /// Every normalisation, in a fixed order (for validation grids).
    pub const ALL: [Normalisation; 4] = [
        Normalisation::Joint,
        Normalisation::Conditional,
        Normalisation::Normalised,
        Normalisation::Pmi,
    ];

    /// Short name (`joint`, `conditional`, `normalised`, `pmi`).
    pub fn name(self) -> &'static str {
        match self {
            Normalisation::Joint => "joint",
            Normalisation::Conditional => "conditional",
            Normalisation::Normalised => "normalised",
            Normalisation::Pmi => "pmi",
        }
    }
}

/// Training options for [`Mrf2`] and [`Mrf3`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CooccurrenceParams {
    /// Added to every cell of the count table (finite, in [0, 1e6]; > 0 keeps all
    /// potentials positive).
    pub pseudo_count: f64,
    /// Frequencies → potentials.
    pub normalisation: Normalisation,
    /// Coupling strength: every potential is raised to this power (finite, in
    /// [0, [`MAX_COUPLING`]]; 1 = the normalised frequencies as they are, 0 =
    /// independent places).
    pub coupling: f64,
}

/// Largest coupling exponent.
pub const MAX_COUPLING: f64 = 10.0;

impl CooccurrenceParams {
    /// Every numeric setting against its documented domain (the one check: training,
    /// the command line and settings files call it).
    pub fn check(&self) -> Result<(), DomainError> {
        domain::closed("pseudo_count", self.pseudo_count, 0.0, 1e6)?;
        domain::closed("coupling", self.coupling, 0.0, MAX_COUPLING)
    }
}

impl Default for CooccurrenceParams {
    /// Pseudo-count 1, joint-frequency normalisation, coupling 1 (the paper-style MRF).
    fn default() -> Self {
        CooccurrenceParams {
            pseudo_count: 1.0,
            normalisation: Normalisation::Joint,
            coupling: 1.0,
        }
    }
}

/// Result of [`MrfModel::log_likelihood_labelled`].
#[derive(Clone, Debug, PartialEq)]
pub struct LabelledLikelihood {
    /// `ln score(labels) − log Z_Bethe` (natural log), without evidence.
    pub log_likelihood: f64,
    /// The BP run that gave `log Z_Bethe` (check `converged`).
    pub bp: BpResult,
}

/// Common interface of [`Mrf2`] and [`Mrf3`].
pub trait MrfModel {
    /// Number of classes `C`.
    fn num_classes(&self) -> usize;

    /// Adds the dependency factors (pairwise or triple) of `map` to `fg`.
    fn add_dependency_factors(&self, map: &TopoMap, fg: &mut FactorGraph) -> Result<(), MrfError>;

    /// The factor graph of `map`: one variable per place, the dependency
    /// factors, then (if given) one unary factor per place holding its evidence
    /// row (`evidence[i][c] = α_i^c`, finite, ≥ 0, not all zero).
    fn factor_graph(
        &self,
        map: &TopoMap,
        evidence: Option<&[Vec<f64>]>,
    ) -> Result<FactorGraph, MrfError> {
        let c = self.num_classes();
        check_map(map, c)?;
        let n = map.num_places();
        let mut fg = FactorGraph::new(vec![c; n])?;
        self.add_dependency_factors(map, &mut fg)?;
        if let Some(ev) = evidence {
            if ev.len() != n {
                return Err(MrfError::BadInput(format!(
                    "map {}: {} evidence rows for {n} places",
                    map.name,
                    ev.len()
                )));
            }
            for (i, row) in ev.iter().enumerate() {
                let pid = map.place(i).id;
                if row.len() != c {
                    return Err(MrfError::BadInput(format!(
                        "map {}, place {pid}: evidence row has {} values, expected {c}",
                        map.name,
                        row.len()
                    )));
                }
                if row.iter().any(|x| !x.is_finite() || *x < 0.0) || row.iter().all(|&x| x == 0.0) {
                    return Err(MrfError::BadInput(format!(
                        "map {}, place {pid}: evidence must be finite, ≥ 0 and not all zero, got {row:?}",
                        map.name
                    )));
                }
                fg.add_factor(vec![i], row.clone())?;
            }
        }
        Ok(fg)
    }

    /// Marginals `P(Y_i | evidence)` by loopy BP.
    fn infer(
        &self,
        map: &TopoMap,
        evidence: &[Vec<f64>],
        opts: &BpOptions,
    ) -> Result<BpResult, MrfError> {
        let fg = self.factor_graph(map, Some(evidence))?;
        loopy_bp(&fg, opts)
    }

    /// Log-likelihood of a full labelling without evidence (for novelty
    /// detection): `ln ∏ ψ(labels) − log Z_Bethe`. Only as good as the Bethe
    /// approximation (exact on trees); check `bp.converged`.
    fn log_likelihood_labelled(
        &self,
        map: &TopoMap,
        labels: &[ClassId],
        opts: &BpOptions,
    ) -> Result<LabelledLikelihood, MrfError> {
        let (mut ll, bp) =
            self.log_likelihoods_labelled(map, std::slice::from_ref(&labels.to_vec()), opts)?;
        Ok(LabelledLikelihood {
            log_likelihood: ll.pop().unwrap_or(f64::NAN),
            bp,
        })
    }

    /// [`MrfModel::log_likelihood_labelled`] of several labellings of one map with
    /// one BP run (`log Z_Bethe` does not depend on the labels): the
    /// log-likelihoods in the order given, and the BP result.
    fn log_likelihoods_labelled(
        &self,
        map: &TopoMap,
        labellings: &[Vec<ClassId>],
        opts: &BpOptions,
    ) -> Result<(Vec<f64>, BpResult), MrfError> {
        let fg = self.factor_graph(map, None)?;
        let mut scores = Vec::with_capacity(labellings.len());
        for labels in labellings {
            if labels.len() != map.num_places() {
                return Err(MrfError::BadInput(format!(
                    "map {}: {} labels for {} places",
                    map.name,
                    labels.len(),
                    map.num_places()
                )));
            }
            let x: Vec<usize> = labels.iter().map(|&l| l as usize).collect();
            scores.push(fg.log_score(&x)?);
        }
        let bp = loopy_bp(&fg, opts)?;
        Ok((scores.iter().map(|s| s - bp.log_z_bethe).collect(), bp))
    }
}

fn check_map(map: &TopoMap, c: usize) -> Result<(), MrfError> {
    if map.classes.len() != c {
        return Err(MrfError::BadInput(format!(
            "map {} has {} classes, the model {c}",
            map.name,
            map.classes.len()
        )));
    }
    Ok(())
}

fn check_params(p: &CooccurrenceParams) -> Result<(), MrfError> {
    p.check().map_err(|e| MrfError::BadOptions(e.to_string()))
}

fn num_classes_of(maps: &[TopoMap]) -> Result<usize, MrfError> {
    let first = maps
        .first()
        .ok_or_else(|| MrfError::BadInput("no training maps".into()))?;
    let c = first.classes.len();
    for m in maps {
        check_map(m, c)?;
    }
    Ok(c)
}

/// Ground-truth class of every place (checked against `c`).
fn classes_of(map: &TopoMap, c: usize) -> Result<Vec<Option<usize>>, MrfError> {
    map.places()
        .map(|p| match p.class {
            Some(k) if (k as usize) < c => Ok(Some(k as usize)),
            Some(k) => Err(MrfError::BadInput(format!(
                "map {}, place {}: class {k} out of range ({c} classes)",
                map.name, p.id
            ))),
            None => Ok(None),
        })
        .collect()
}

/// Every connected triple `(A, P, B)` of a map: pivot `P`, neighbours `A < B`;
/// sorted by pivot, then `A`, then `B`.
pub fn connected_triples(map: &TopoMap) -> Vec<[usize; 3]> {
    let mut out = Vec::new();
    for p in 0..map.num_places() {
        let nb = map.neighbors(p);
        for (j, &a) in nb.iter().enumerate() {
            for &b in &nb[j + 1..] {
                out.push([a, p, b]);
            }
        }
    }
    out
}

/// Every undirected edge `(a, b)` with `a < b`, sorted.
pub fn edges_sorted(map: &TopoMap) -> Vec<[usize; 2]> {
    let mut out = Vec::new();
    for a in 0..map.num_places() {
        for b in map.neighbors(a) {
            if a < b {
                out.push([a, b]);
            }
        }
    }
    out
}

/// Joint frequencies (with pseudo-count) → potentials, for a table whose axes all have `c` states.
fn potentials_from_counts(
    counts: &[f64],
    c: usize,
    arity: u32,
    p: &CooccurrenceParams,
) -> Vec<f64> {
    let total: f64 = counts.iter().sum::<f64>() + p.pseudo_count * counts.len() as f64;
    let joint: Vec<f64> = if total > 0.0 {
        counts
            .iter()
            .map(|&n| (n + p.pseudo_count) / total)
            .collect()
    } else {
        vec![1.0 / counts.len() as f64; counts.len()]
    };
    // Marginal of every axis.
    let arity = arity as usize;
    let mut marg = vec![vec![0.0; c]; arity];
    for (idx, &q) in joint.iter().enumerate() {
        let mut r = idx;
        for k in (0..arity).rev() {
            marg[k][r % c] += q;
            r /= c;
        }
    }
    // Which axes divide the joint, and with which power.
    let (axes, power): (Vec<usize>, f64) = match p.normalisation {
        Normalisation::Joint => (Vec::new(), 1.0),
        Normalisation::Pmi => ((0..arity).collect(), 1.0),
        Normalisation::Normalised => ((0..arity).collect(), 0.5),
        // MRF-2: the first variable; MRF-3: the pivot (the middle axis).
        Normalisation::Conditional => (vec![if arity == 3 { 1 } else { 0 }], 1.0),
    };
    joint
        .iter()
        .enumerate()
        .map(|(idx, &q)| {
            let mut digits = [0usize; 8];
            let mut r = idx;
            for k in (0..arity).rev() {
                digits[k] = r % c;
                r /= c;
            }
            let denom: f64 = axes.iter().map(|&k| marg[k][digits[k]]).product();
            // A zero marginal means the whole slice is zero: potential 0.
            let v = if denom > 0.0 {
                q / denom.powf(power)
            } else {
                0.0
            };
            if p.coupling == 1.0 {
                v
            } else {
                v.powf(p.coupling)
            }
        })
        .collect()
}

/// MRF with a co-occurrence potential on every clique of `K` places (see the module
/// docs): [`Mrf2`] (edges) and [`Mrf3`] (connected triples `A–P–B`).
#[derive(Clone, Debug, PartialEq)]
pub struct CooccurrenceMrf<const K: usize> {
    num_classes: usize,
    counts: Vec<f64>,
    potential: Arc<[f64]>,
}

/// MRF with a pairwise co-occurrence potential on every edge (the paper's MRF-2).
pub type Mrf2 = CooccurrenceMrf<2>;

/// MRF with a three-variable co-occurrence potential on every connected triple
/// `A–P–B` (the paper's MRF-3); see the module docs.
pub type Mrf3 = CooccurrenceMrf<3>;

/// The cliques a co-occurrence MRF puts its factors on, in factor variable order.
pub trait Cliques<const K: usize> {
    /// Every clique of `map`.
    fn cliques(map: &TopoMap) -> Vec<[usize; K]>;
}

impl Cliques<2> for Mrf2 {
    fn cliques(map: &TopoMap) -> Vec<[usize; 2]> {
        edges_sorted(map)
    }
}

impl Cliques<3> for Mrf3 {
    fn cliques(map: &TopoMap) -> Vec<[usize; 3]> {
        connected_triples(map)
    }
}

impl<const K: usize> CooccurrenceMrf<K>
where
    Self: Cliques<K>,
{
    /// Counts class tuples over the cliques of the training maps (edges for MRF-2,
    /// paths `A–P–B` for MRF-3), each in both orientations (the tuple and its
    /// reverse), then turns the counts into the potential.
    pub fn train(maps: &[TopoMap], params: &CooccurrenceParams) -> Result<Self, MrfError> {
        check_params(params)?;
        let c = num_classes_of(maps)?;
        let mut counts = vec![0.0; c.pow(K as u32)];
        for m in maps {
            let cls = classes_of(m, c)?;
            'clique: for clique in Self::cliques(m) {
                let mut t = [0usize; K];
                for (x, &p) in t.iter_mut().zip(&clique) {
                    match cls[p] {
                        Some(class) => *x = class,
                        None => continue 'clique,
                    }
                }
                counts[t.iter().fold(0, |i, &x| i * c + x)] += 1.0;
                counts[t.iter().rev().fold(0, |i, &x| i * c + x)] += 1.0;
            }
        }
        let potential = potentials_from_counts(&counts, c, K as u32, params).into();
        Ok(CooccurrenceMrf {
            num_classes: c,
            counts,
            potential,
        })
    }

    /// Raw tuple counts at `[(a · C + b) · C + …]` in factor variable order (MRF-3:
    /// ends `a`, `b`, pivot `p` at `[(a · C + p) · C + b]`); symmetric under reversal.
    pub fn counts(&self) -> &[f64] {
        &self.counts
    }

    /// The potential at the same index as [`CooccurrenceMrf::counts`].
    pub fn potential(&self) -> &[f64] {
        &self.potential
    }
}

impl<const K: usize> MrfModel for CooccurrenceMrf<K>
where
    Self: Cliques<K>,
{
    fn num_classes(&self) -> usize {
        self.num_classes
    }

    fn add_dependency_factors(&self, map: &TopoMap, fg: &mut FactorGraph) -> Result<(), MrfError> {
        for clique in Self::cliques(map) {
            fg.add_factor_shared(clique.to_vec(), self.potential.clone())?;
        }
        Ok(())
    }
}
