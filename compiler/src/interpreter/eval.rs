//! The precompiled evaluator: flat CSR arrays plus reusable scratch buffers.

use graphspn_runtime::EvidenceError;
use thiserror::Error;

use super::evidence::Evidence;
use crate::spn::{Node, Spn, SpnError};

const NEG_INF: f64 = f64::NEG_INFINITY;
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

    /// Checks `fixed` and `evidence` and fills the per-slot leaf log-values.
    fn prepare(
        &mut self,
        fixed: &[Option<u32>],
        evidence: &Evidence,
    ) -> Result<(), InferenceError> {
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
        for (v, row) in evidence.rows().iter().enumerate() {
            let base = self.slot_start[v];
            for (c, &a) in row.iter().enumerate() {
                let excluded = matches!(fixed[v], Some(f) if f as usize != c);
                self.slot_log[base + c] = if excluded { NEG_INF } else { a.ln() };
            }
        }
        Ok(())
    }

    /// Upward sum-product pass in log space; returns `ln S`.
    fn upward(&mut self) -> f64 {
        let n = self.kind.len();
        for i in 0..n {
            let (s, e) = (self.edge_start[i] as usize, self.edge_start[i + 1] as usize);
            self.val[i] = match self.kind[i] {
                LEAF => self.slot_log[self.leaf_slot[i] as usize],
                SUM => {
                    let mut m = NEG_INF;
                    for k in s..e {
                        let x = self.log_w[k] + self.val[self.child[k] as usize];
                        if x > m {
                            m = x;
                        }
                    }
                    if m == NEG_INF {
                        NEG_INF
                    } else {
                        let mut acc = 0.0;
                        for k in s..e {
                            acc += (self.log_w[k] + self.val[self.child[k] as usize] - m).exp();
                        }
                        m + acc.ln()
                    }
                }
                _ => {
                    let mut acc = 0.0;
                    for k in s..e {
                        acc += self.val[self.child[k] as usize];
                    }
                    acc
                }
            };
        }
        self.val[self.root]
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
        self.prepare(fixed, evidence)?;
        let ll = self.upward();
        if ll == NEG_INF {
            return Err(EvidenceError::ZeroLikelihood.into());
        }
        Ok(ll)
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
        let log_likelihood = self.log_likelihood(fixed, evidence)?;
        let n = self.kind.len();
        self.flow.iter_mut().for_each(|f| *f = 0.0);
        self.flow[self.root] = 1.0;
        self.slot_acc.iter_mut().for_each(|p| *p = 0.0);
        for i in (0..n).rev() {
            let f = self.flow[i];
            if f == 0.0 {
                continue;
            }
            let (s, e) = (self.edge_start[i] as usize, self.edge_start[i + 1] as usize);
            match self.kind[i] {
                LEAF => self.slot_acc[self.leaf_slot[i] as usize] += f,
                SUM => {
                    // f > 0 implies v(i) > 0, so val[i] is finite.
                    let vi = self.val[i];
                    for k in s..e {
                        let c = self.child[k] as usize;
                        self.flow[c] += f * (self.log_w[k] + self.val[c] - vi).exp();
                    }
                }
                _ => {
                    for k in s..e {
                        self.flow[self.child[k] as usize] += f;
                    }
                }
            }
        }
        let probs = self
            .classes
            .iter()
            .enumerate()
            .map(|(v, &k)| {
                let base = self.slot_start[v];
                let mut row = self.slot_acc[base..base + k as usize].to_vec();
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
    }

    /// Max-product upward pass and backtracking: at a sum the child maximising
    /// `ln w + value` (ties: the lowest child position), at a product every child.
    /// See [`Mpe`] for what the answer means for selective and non-selective SPNs.
    pub fn mpe(
        &mut self,
        fixed: &[Option<u32>],
        evidence: &Evidence,
    ) -> Result<Mpe, InferenceError> {
        self.prepare(fixed, evidence)?;
        let n = self.kind.len();
        for i in 0..n {
            let (s, e) = (self.edge_start[i] as usize, self.edge_start[i + 1] as usize);
            self.val[i] = match self.kind[i] {
                LEAF => self.slot_log[self.leaf_slot[i] as usize],
                SUM => {
                    let mut m = NEG_INF;
                    let mut best = s;
                    for k in s..e {
                        let x = self.log_w[k] + self.val[self.child[k] as usize];
                        if x > m {
                            m = x;
                            best = k;
                        }
                    }
                    self.arg[i] = best as u32;
                    m
                }
                _ => {
                    let mut acc = 0.0;
                    for k in s..e {
                        acc += self.val[self.child[k] as usize];
                    }
                    acc
                }
            };
        }
        let log_max_product = self.val[self.root];
        if log_max_product == NEG_INF {
            return Err(EvidenceError::ZeroLikelihood.into());
        }
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
