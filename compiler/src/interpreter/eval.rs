//! The precompiled evaluator: flat CSR arrays plus reusable scratch buffers.

use graphspn_runtime::EvidenceError;
use thiserror::Error;

use super::evidence::Evidence;
use crate::spn::{Node, Spn, SpnError};

const NEG_INF: f64 = f64::NEG_INFINITY;

/// Queries answered together by the `*_batch` methods of [`Evaluator`].
pub const BATCH: usize = 8;
const LEAF: u8 = 0;
const SUM: u8 = 1;
const PRODUCT: u8 = 2;

/// Why a query could not be answered.
#[derive(Clone, Debug, PartialEq, Error)]
pub enum InferenceError {
    /// The SPN failed [`Spn::validate`].
    #[error("invalid SPN: {0}")]
    InvalidSpn(#[from] SpnError),
    /// The evidence is invalid, or has probability zero
    /// ([`EvidenceError::ZeroLikelihood`]) given the fixed classes.
    #[error("{0}")]
    Evidence(#[from] EvidenceError),
    /// `fixed` does not have one entry per variable.
    #[error("fixed has {found} entries but the SPN has {expected} variables")]
    FixedWrongLength {
        /// Number of variables.
        expected: usize,
        /// Number of entries given.
        found: usize,
    },
    /// A fixed class does not exist.
    #[error("fixed class {class} of variable {var} is out of range (it has {classes} classes)")]
    FixedClassOutOfRange {
        /// The variable.
        var: usize,
        /// The fixed class.
        class: u32,
        /// Classes of the variable.
        classes: u32,
    },
}

/// Posterior marginals and the log-likelihood of one query.
#[derive(Clone, Debug, PartialEq)]
pub struct Marginals {
    /// `ln S(evidence, fixed)`: natural log of the likelihood (finite).
    pub log_likelihood: f64,
    /// `probs[v][c] = P(Y_v = c | evidence, fixed)`; every row sums to 1
    /// (within a few ulps); a fixed variable's row is one-hot.
    pub probs: Vec<Vec<f64>>,
}

/// A max-product (MPE) answer.
///
/// For a *selective* SPN (at most one non-zero child per sum for any full
/// assignment), `assignment` is the exact most probable joint assignment and
/// `log_max_product == log_probability`. For a non-selective SPN max-product is the
/// standard approximation: `log_max_product ≤ log_probability ≤ ln max_x P(x, evidence)`.
#[derive(Clone, Debug, PartialEq)]
pub struct Mpe {
    /// One class per variable (fixed variables keep their class).
    pub assignment: Vec<u32>,
    /// Natural log of the value of the best induced tree (weights × evidence along it).
    pub log_max_product: f64,
    /// Exact `ln S` with every variable fixed to `assignment` (same evidence).
    pub log_probability: f64,
}

/// A validated SPN flattened into CSR arrays, with scratch buffers reused across
/// queries. Each query is `O(E)` time (E = edges) and allocates only its result.
///
/// All values are natural logs in `f64` (leaves: `ln α`, `-∞` for a class excluded by
/// `fixed` or α = 0), so tiny likelihoods (e.g. `1e-300` on every variable) never
/// underflow. Sums use a max-shifted log-sum-exp (error ≤ `(n+3)·ε·(1+|v|)` per sum
/// node of n children, see [`graphspn_runtime::numerics`]); products add logs.
#[derive(Clone, Debug)]
pub struct Evaluator {
    classes: Vec<u32>,
    /// `slot_start[v] + c` is the flat slot of `(v, c)`.
    slot_start: Vec<usize>,
    kind: Vec<u8>,
    /// Edges of node `n` are `edge_start[n]..edge_start[n + 1]`.
    edge_start: Vec<u32>,
    child: Vec<u32>,
    /// `ln w` per edge (0 for product edges).
    log_w: Vec<f64>,
    /// Flat slot of each leaf node (unused for sums and products).
    leaf_slot: Vec<u32>,
    root: usize,
    // Scratch.
    slot_log: Vec<f64>,
    val: Vec<f64>,
    flow: Vec<f64>,
    slot_acc: Vec<f64>,
    arg: Vec<u32>,
    stack: Vec<u32>,
}

/// What the upward pass computes at sum nodes.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Pass {
    /// Log-sum-exp of the weighted children: `ln S`.
    SumProduct,
    /// The largest weighted child, its edge recorded in `arg` (ties: the lowest).
    MaxProduct,
}

impl Evaluator {
    /// Validates `spn` ([`Spn::validate`]) and flattens it.
    pub fn new(spn: &Spn) -> Result<Self, SpnError> {
        spn.validate()?;
        let n = spn.nodes.len();
        let e = spn.num_edges();
        let mut slot_start = Vec::with_capacity(spn.classes.len() + 1);
        let mut total = 0usize;
        for &k in &spn.classes {
            slot_start.push(total);
            total += k as usize;
        }
        slot_start.push(total);
        let mut kind = Vec::with_capacity(n);
        let mut edge_start = Vec::with_capacity(n + 1);
        let mut child = Vec::with_capacity(e);
        let mut log_w = Vec::with_capacity(e);
        let mut leaf_slot = Vec::with_capacity(n);
        for node in &spn.nodes {
            edge_start.push(child.len() as u32);
            match node {
                Node::Leaf { var, class } => {
                    kind.push(LEAF);
                    leaf_slot.push((slot_start[*var as usize] + *class as usize) as u32);
                }
                Node::Sum { children, weights } => {
                    kind.push(SUM);
                    leaf_slot.push(u32::MAX);
                    child.extend_from_slice(children);
                    log_w.extend(weights.iter().map(|w| w.ln()));
                }
                Node::Product { children } => {
                    kind.push(PRODUCT);
                    leaf_slot.push(u32::MAX);
                    child.extend_from_slice(children);
                    log_w.extend(std::iter::repeat_n(0.0, children.len()));
                }
            }
        }
        edge_start.push(child.len() as u32);
        Ok(Evaluator {
            classes: spn.classes.clone(),
            slot_start,
            kind,
            edge_start,
            child,
            log_w,
            leaf_slot,
            root: spn.root as usize,
            slot_log: vec![0.0; total],
            val: vec![0.0; n],
            flow: vec![0.0; n],
            slot_acc: vec![0.0; total],
            arg: vec![0; n],
            stack: Vec::new(),
        })
    }

    /// Classes per variable.
    pub fn classes(&self) -> &[u32] {
        &self.classes
    }

    /// Number of edges.
    pub fn num_edges(&self) -> usize {
        self.child.len()
    }

    /// Checks `fixed` and `evidence` of one query.
    fn check(&self, fixed: &[Option<u32>], evidence: &Evidence) -> Result<(), InferenceError> {
        let nv = self.classes.len();
        if fixed.len() != nv {
            return Err(InferenceError::FixedWrongLength {
                expected: nv,
                found: fixed.len(),
            });
        }
        for (var, (f, &k)) in fixed.iter().zip(&self.classes).enumerate() {
            if let Some(class) = *f
                && class >= k
            {
                return Err(InferenceError::FixedClassOutOfRange {
                    var,
                    class,
                    classes: k,
                });
            }
        }
        evidence.validate(&self.classes)?;
        Ok(())
    }

    /// Checks the `K` queries and fills the per-slot leaf log-values of each lane (a
    /// lane whose query is invalid gets `-∞` everywhere), and sizes the scratch
    /// buffers for `K` lanes. Returns each lane's check.
    fn prepare<const K: usize>(
        &mut self,
        fixed: [&[Option<u32>]; K],
        evidence: [&Evidence; K],
    ) -> [Result<(), InferenceError>; K] {
        let total = self.slot_start[self.classes.len()];
        let n = self.kind.len();
        self.slot_log.resize(total * K, 0.0);
        self.val.resize(n * K, 0.0);
        self.arg.resize(n * K, 0);
        let checks: [Result<(), InferenceError>; K] =
            std::array::from_fn(|l| self.check(fixed[l], evidence[l]));
        let slots = self.slot_log.as_chunks_mut::<K>().0;
        for (l, ok) in checks.iter().enumerate() {
            if ok.is_err() {
                slots.iter_mut().for_each(|s| s[l] = NEG_INF);
                continue;
            }
            for (v, row) in evidence[l].rows().iter().enumerate() {
                let base = self.slot_start[v];
                for (c, &a) in row.iter().enumerate() {
                    let excluded = matches!(fixed[l][v], Some(f) if f as usize != c);
                    slots[base + c][l] = if excluded { NEG_INF } else { a.ln() };
                }
            }
        }
        checks
    }

    /// Upward pass in log space over `K` lanes (each lane does the arithmetic of a
    /// one-lane pass, exponentials aside: see [`exp_lanes`]); returns the root's value
    /// per lane (see [`Pass`] for sums).
    fn upward<const K: usize>(&mut self, pass: Pass) -> [f64; K] {
        let slots = self.slot_log.as_chunks::<K>().0;
        let val = self.val.as_chunks_mut::<K>().0;
        let arg = self.arg.as_chunks_mut::<K>().0;
        for i in 0..self.kind.len() {
            let (s, e) = (self.edge_start[i] as usize, self.edge_start[i + 1] as usize);
            val[i] = match self.kind[i] {
                LEAF => slots[self.leaf_slot[i] as usize],
                SUM => {
                    let mut m = [NEG_INF; K];
                    let mut best = [s; K];
                    for k in s..e {
                        let c = val[self.child[k] as usize];
                        for l in 0..K {
                            let x = self.log_w[k] + c[l];
                            if x > m[l] {
                                m[l] = x;
                                best[l] = k;
                            }
                        }
                    }
                    if pass == Pass::MaxProduct {
                        arg[i] = best.map(|b| b as u32);
                        m
                    } else {
                        let mut acc = [0.0; K];
                        for k in s..e {
                            let c = val[self.child[k] as usize];
                            let t: [f64; K] =
                                exp_lanes(std::array::from_fn(|l| self.log_w[k] + c[l] - m[l]));
                            // A lane with m = -∞ sums NaNs here; its value is -∞ below.
                            for l in 0..K {
                                acc[l] += t[l];
                            }
                        }
                        std::array::from_fn(|l| {
                            if m[l] == NEG_INF {
                                NEG_INF
                            } else {
                                m[l] + acc[l].ln()
                            }
                        })
                    }
                }
                _ => {
                    let mut acc = [0.0; K];
                    for k in s..e {
                        let c = val[self.child[k] as usize];
                        for l in 0..K {
                            acc[l] += c[l];
                        }
                    }
                    acc
                }
            };
        }
        val[self.root]
    }

    /// `ln S(evidence, fixed)`: variables with `fixed[v] = Some(c)` are restricted to
    /// class `c` (the indicators of their other classes are 0), all others are
    /// summed out; `α` multiplies every leaf. Returns `-∞` only through the
    /// [`EvidenceError::ZeroLikelihood`] error, never as a value.
    pub fn log_likelihood(
        &mut self,
        fixed: &[Option<u32>],
        evidence: &Evidence,
    ) -> Result<f64, InferenceError> {
        let [r] = self.root_lanes(Pass::SumProduct, [fixed], [evidence]);
        r
    }

    /// [`Evaluator::log_likelihood`] of [`BATCH`] queries in one pass over the network: its
    /// arrays are read once for all lanes, and lanes take the exponentials four at a
    /// time (a vector exp within 1 ulp of `f64::exp`), so each lane agrees with the
    /// one-query call to a few ulps of every sum (errors are the same).
    pub fn log_likelihood_batch(
        &mut self,
        fixed: [&[Option<u32>]; BATCH],
        evidence: [&Evidence; BATCH],
    ) -> [Result<f64, InferenceError>; BATCH] {
        self.root_lanes(Pass::SumProduct, fixed, evidence)
    }

    /// `ln S` and `P(Y_v = c | evidence, fixed)` for every variable and class, in one
    /// upward and one downward pass.
    ///
    /// The downward pass propagates *flows* `f(n) = v(n)·∂S/∂v(n) / S ∈ [0, 1]` (the
    /// derivative of `ln S` with respect to `ln v(n)`): `f(root) = 1`; a product passes
    /// its flow to every child; a sum passes `f(n)·w·v(c)/v(n)`, computed as
    /// `exp(ln w + ln v(c) − ln v(n))`. A node of value 0 (a product with a zero child,
    /// a leaf with α = 0 or excluded by `fixed`) has flow exactly 0, so zero children
    /// need no special case and nothing is ever divided by 0. Then
    /// `P(Y_v = c | …) = Σ flows of the leaves (v, c)`; each row is finally divided by
    /// its sum (mathematically 1) to remove rounding drift. Absolute error of each
    /// probability is a small multiple of `ε·(1 + |ln S|)` times the number of edges on
    /// the paths involved.
    pub fn marginals(
        &mut self,
        fixed: &[Option<u32>],
        evidence: &Evidence,
    ) -> Result<Marginals, InferenceError> {
        let [r] = self.marginals_lanes([fixed], [evidence]);
        r
    }

    /// [`Evaluator::marginals`] of [`BATCH`] queries in one upward and one downward pass
    /// (see [`Evaluator::log_likelihood_batch`] for how lanes agree with single calls).
    pub fn marginals_batch(
        &mut self,
        fixed: [&[Option<u32>]; BATCH],
        evidence: [&Evidence; BATCH],
    ) -> [Result<Marginals, InferenceError>; BATCH] {
        self.marginals_lanes(fixed, evidence)
    }

    /// [`Evaluator::marginals`] of `K` queries in `K` lanes.
    fn marginals_lanes<const K: usize>(
        &mut self,
        fixed: [&[Option<u32>]; K],
        evidence: [&Evidence; K],
    ) -> [Result<Marginals, InferenceError>; K] {
        let lls = self.root_lanes(Pass::SumProduct, fixed, evidence);
        let n = self.kind.len();
        let total = self.slot_start[self.classes.len()];
        self.flow.clear();
        self.flow.resize(n * K, 0.0);
        self.slot_acc.clear();
        self.slot_acc.resize(total * K, 0.0);
        let flow = self.flow.as_chunks_mut::<K>().0;
        let slot_acc = self.slot_acc.as_chunks_mut::<K>().0;
        let val = self.val.as_chunks::<K>().0;
        // Lanes without an answer keep flow 0 everywhere.
        flow[self.root] = std::array::from_fn(|l| if lls[l].is_ok() { 1.0 } else { 0.0 });
        for i in (0..n).rev() {
            let f = flow[i];
            if f.iter().all(|&x| x == 0.0) {
                continue;
            }
            let (s, e) = (self.edge_start[i] as usize, self.edge_start[i + 1] as usize);
            match self.kind[i] {
                LEAF => {
                    let acc = &mut slot_acc[self.leaf_slot[i] as usize];
                    for l in 0..K {
                        acc[l] += f[l];
                    }
                }
                SUM => {
                    // f > 0 implies v(i) > 0, so val[i] is finite; a lane with
                    // f = 0 adds exactly 0.
                    let vi = val[i];
                    for k in s..e {
                        let ci = self.child[k] as usize;
                        let t: [f64; K] = exp_lanes(std::array::from_fn(|l| {
                            if f[l] == 0.0 {
                                NEG_INF
                            } else {
                                self.log_w[k] + val[ci][l] - vi[l]
                            }
                        }));
                        let c = &mut flow[ci];
                        for l in 0..K {
                            c[l] += f[l] * t[l];
                        }
                    }
                }
                _ => {
                    for k in s..e {
                        let c = &mut flow[self.child[k] as usize];
                        for l in 0..K {
                            c[l] += f[l];
                        }
                    }
                }
            }
        }
        let slot_acc = &*slot_acc;
        let classes = &self.classes;
        let slot_start = &self.slot_start;
        let mut lane = 0;
        lls.map(|ll| {
            let l = lane;
            lane += 1;
            let log_likelihood = ll?;
            let probs = classes
                .iter()
                .enumerate()
                .map(|(v, &k)| {
                    let base = slot_start[v];
                    let mut row: Vec<f64> = slot_acc[base..base + k as usize]
                        .iter()
                        .map(|a| a[l])
                        .collect();
                    let total: f64 = row.iter().sum();
                    if total > 0.0 {
                        row.iter_mut().for_each(|p| *p /= total);
                    }
                    row
                })
                .collect();
            Ok(Marginals {
                log_likelihood,
                probs,
            })
        })
    }

    /// Max-product upward pass and backtracking: at a sum the child maximising
    /// `ln w + value` (ties: the lowest child position), at a product every child.
    /// See [`Mpe`] for what the answer means for selective and non-selective SPNs.
    pub fn mpe(
        &mut self,
        fixed: &[Option<u32>],
        evidence: &Evidence,
    ) -> Result<Mpe, InferenceError> {
        let log_max_product = self.log_max_product(fixed, evidence)?;
        let mut assignment = vec![0u32; self.classes.len()];
        self.stack.clear();
        self.stack.push(self.root as u32);
        while let Some(i) = self.stack.pop() {
            let i = i as usize;
            match self.kind[i] {
                LEAF => {
                    let slot = self.leaf_slot[i] as usize;
                    let v = self.slot_start.partition_point(|&s| s <= slot) - 1;
                    assignment[v] = (slot - self.slot_start[v]) as u32;
                }
                // One lane: `arg[i]` is node i's best edge.
                SUM => self.stack.push(self.child[self.arg[i] as usize]),
                _ => {
                    let (s, e) = (self.edge_start[i] as usize, self.edge_start[i + 1] as usize);
                    self.stack.extend_from_slice(&self.child[s..e]);
                }
            }
        }
        let full: Vec<Option<u32>> = assignment.iter().map(|&c| Some(c)).collect();
        let log_probability = self.log_likelihood(&full, evidence)?;
        Ok(Mpe {
            assignment,
            log_max_product,
            log_probability,
        })
    }

    /// The max-product value `ln max_y S(y, evidence, fixed)` of [`Evaluator::mpe`]
    /// (the upward max pass alone: no backtracking, no second pass). With every
    /// variable fixed it is the value the network's max-product gives that labelling.
    pub fn log_max_product(
        &mut self,
        fixed: &[Option<u32>],
        evidence: &Evidence,
    ) -> Result<f64, InferenceError> {
        let [r] = self.root_lanes(Pass::MaxProduct, [fixed], [evidence]);
        r
    }

    /// [`Evaluator::log_max_product`] of [`BATCH`] queries in one pass (no exponentials:
    /// each lane's result is bit-identical to the one-query call).
    pub fn log_max_product_batch(
        &mut self,
        fixed: [&[Option<u32>]; BATCH],
        evidence: [&Evidence; BATCH],
    ) -> [Result<f64, InferenceError>; BATCH] {
        self.root_lanes(Pass::MaxProduct, fixed, evidence)
    }

    /// The root's value of `K` queries in `K` lanes after one upward `pass`:
    /// [`Evaluator::log_likelihood`] or [`Evaluator::log_max_product`].
    fn root_lanes<const K: usize>(
        &mut self,
        pass: Pass,
        fixed: [&[Option<u32>]; K],
        evidence: [&Evidence; K],
    ) -> [Result<f64, InferenceError>; K] {
        let checks = self.prepare(fixed, evidence);
        let root = self.upward::<K>(pass);
        lane_results(checks, root)
    }
}

/// `e^x` of every lane: groups of four with `wide`'s vector exp (relative error below
/// 1 ulp for normal results, measured against `f64::exp`; `e^{-∞} = 0`), the rest
/// (and one-query calls) with `f64::exp`.
#[inline]
fn exp_lanes<const K: usize>(x: [f64; K]) -> [f64; K] {
    let mut out = [0.0; K];
    let (groups, rest) = x.as_chunks::<4>();
    let (out_groups, out_rest) = out.as_chunks_mut::<4>();
    for (o, g) in out_groups.iter_mut().zip(groups) {
        *o = wide::f64x4::from(*g).exp().to_array();
    }
    for (o, &v) in out_rest.iter_mut().zip(rest) {
        *o = v.exp();
    }
    out
}

/// Each lane's root value, or its check's error, or [`EvidenceError::ZeroLikelihood`]
/// for a value of `-∞`.
fn lane_results<const K: usize>(
    checks: [Result<(), InferenceError>; K],
    root: [f64; K],
) -> [Result<f64, InferenceError>; K] {
    let mut lane = 0;
    checks.map(|check| {
        let v = root[lane];
        lane += 1;
        check?;
        if v == NEG_INF {
            return Err(EvidenceError::ZeroLikelihood.into());
        }
        Ok(v)
    })
}

/// One-off [`Evaluator::log_likelihood`] (validates and flattens `spn` first).
pub fn log_likelihood(
    spn: &Spn,
    fixed: &[Option<u32>],
    evidence: &Evidence,
) -> Result<f64, InferenceError> {
    Evaluator::new(spn)?.log_likelihood(fixed, evidence)
}

/// One-off [`Evaluator::marginals`] (validates and flattens `spn` first).
pub fn marginals(
    spn: &Spn,
    fixed: &[Option<u32>],
    evidence: &Evidence,
) -> Result<Marginals, InferenceError> {
    Evaluator::new(spn)?.marginals(fixed, evidence)
}

/// One-off [`Evaluator::mpe`] (validates and flattens `spn` first).
pub fn mpe(spn: &Spn, fixed: &[Option<u32>], evidence: &Evidence) -> Result<Mpe, InferenceError> {
    Evaluator::new(spn)?.mpe(fixed, evidence)
}
