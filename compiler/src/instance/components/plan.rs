//! One template SPN flattened for evaluation on any component ([`Plan`]: upward,
//! downward and backtracking passes in natural logs), its results on a component
//! without evidence ([`Blank`]), and the partial-sum trees of the decompositions.

use crate::spn::{Node, Spn};

pub(super) const NEG_INF: f64 = f64::NEG_INFINITY;
const LEAF: u8 = 0;
const SUM: u8 = 1;
const PRODUCT: u8 = 2;

/// One template SPN flattened for evaluation on any component (CSR arrays, logs of
/// the weights); leaves index `var × classes + class` of a component's slot row.
#[derive(Clone, Debug)]
pub(super) struct Plan {
    pub(super) kind: Vec<u8>,
    pub(super) edge_start: Vec<u32>,
    pub(super) child: Vec<u32>,
    pub(super) log_w: Vec<f64>,
    pub(super) leaf: Vec<u32>,
    pub(super) root: usize,
}

/// Per-thread scratch of one template pass.
#[derive(Clone, Debug, Default)]
pub(super) struct Scratch {
    pub(super) slots: Vec<f64>,
    pub(super) val: Vec<f64>,
    pub(super) flow: Vec<f64>,
    pub(super) arg: Vec<u32>,
    pub(super) stack: Vec<u32>,
}

impl Plan {
    /// Flattens a validated template SPN whose variables all have `classes` classes.
    pub(super) fn new(spn: &Spn, classes: usize) -> Plan {
        let mut p = Plan {
            kind: Vec::with_capacity(spn.nodes.len()),
            edge_start: Vec::with_capacity(spn.nodes.len() + 1),
            child: Vec::new(),
            log_w: Vec::new(),
            leaf: Vec::with_capacity(spn.nodes.len()),
            root: spn.root as usize,
        };
        for node in &spn.nodes {
            p.edge_start.push(p.child.len() as u32);
            match node {
                Node::Leaf { var, class } => {
                    p.kind.push(LEAF);
                    p.leaf
                        .push((*var as usize * classes + *class as usize) as u32);
                }
                Node::Sum { children, weights } => {
                    p.kind.push(SUM);
                    p.leaf.push(u32::MAX);
                    p.child.extend_from_slice(children);
                    p.log_w.extend(weights.iter().map(|w| w.ln()));
                }
                Node::Product { children } => {
                    p.kind.push(PRODUCT);
                    p.leaf.push(u32::MAX);
                    p.child.extend_from_slice(children);
                    p.log_w.extend(std::iter::repeat_n(0.0, children.len()));
                }
            }
        }
        p.edge_start.push(p.child.len() as u32);
        p
    }

    /// Upward pass over `s.slots`: log-sum-exp (or max, recording the best edge in
    /// `s.arg`, ties to the lowest) at sums, log sums at products. Returns `ln v(root)`.
    pub(super) fn up(&self, s: &mut Scratch, max: bool) -> f64 {
        let n = self.kind.len();
        s.val.clear();
        s.val.resize(n, 0.0);
        if max {
            s.arg.clear();
            s.arg.resize(n, 0);
        }
        for i in 0..n {
            let (a, b) = (self.edge_start[i] as usize, self.edge_start[i + 1] as usize);
            s.val[i] = match self.kind[i] {
                LEAF => s.slots[self.leaf[i] as usize],
                SUM => {
                    let mut m = NEG_INF;
                    let mut best = a;
                    for k in a..b {
                        let x = self.log_w[k] + s.val[self.child[k] as usize];
                        if x > m {
                            m = x;
                            best = k;
                        }
                    }
                    if max {
                        s.arg[i] = best as u32;
                        m
                    } else if m == NEG_INF {
                        NEG_INF
                    } else {
                        let mut acc = 0.0;
                        for k in a..b {
                            acc += (self.log_w[k] + s.val[self.child[k] as usize] - m).exp();
                        }
                        m + acc.ln()
                    }
                }
                _ => {
                    let mut acc = 0.0;
                    for k in a..b {
                        acc += s.val[self.child[k] as usize];
                    }
                    acc
                }
            };
        }
        s.val[self.root]
    }

    /// Downward pass after a sum-product [`Plan::up`]: local posteriors of every
    /// (variable, class) into `out` (rows of `classes`, each divided by its sum to
    /// remove rounding drift). All zeros when the component's value is 0.
    pub(super) fn down(&self, s: &mut Scratch, classes: usize, out: &mut [f64]) {
        out.iter_mut().for_each(|x| *x = 0.0);
        let n = self.kind.len();
        s.flow.clear();
        s.flow.resize(n, 0.0);
        if s.val[self.root] == NEG_INF {
            return;
        }
        s.flow[self.root] = 1.0;
        for i in (0..n).rev() {
            let f = s.flow[i];
            if f == 0.0 {
                continue;
            }
            let (a, b) = (self.edge_start[i] as usize, self.edge_start[i + 1] as usize);
            match self.kind[i] {
                LEAF => out[self.leaf[i] as usize] += f,
                SUM => {
                    let vi = s.val[i];
                    for k in a..b {
                        let c = self.child[k] as usize;
                        s.flow[c] += f * (self.log_w[k] + s.val[c] - vi).exp();
                    }
                }
                _ => {
                    for k in a..b {
                        s.flow[self.child[k] as usize] += f;
                    }
                }
            }
        }
        for row in out.chunks_mut(classes) {
            let total: f64 = row.iter().sum();
            if total > 0.0 {
                row.iter_mut().for_each(|p| *p /= total);
            }
        }
    }

    /// Backtracking after a max-product [`Plan::up`]: the class of every variable
    /// reached (best child at sums, every child at products) into `out[var]`.
    pub(super) fn backtrack(&self, s: &mut Scratch, classes: usize, out: &mut [u32]) {
        s.stack.clear();
        s.stack.push(self.root as u32);
        while let Some(i) = s.stack.pop() {
            let i = i as usize;
            match self.kind[i] {
                LEAF => {
                    let slot = self.leaf[i] as usize;
                    out[slot / classes] = (slot % classes) as u32;
                }
                SUM => s.stack.push(self.child[s.arg[i] as usize]),
                _ => {
                    let (a, b) = (self.edge_start[i] as usize, self.edge_start[i + 1] as usize);
                    s.stack.extend_from_slice(&self.child[a..b]);
                }
            }
        }
    }
}

/// A template's results with no evidence (every `ln α` = 0): exactly what [`Plan::up`]
/// and [`Plan::down`] give any component whose places are all unobserved.
#[derive(Clone, Debug)]
pub(super) struct Blank {
    pub(super) ll: f64,
    pub(super) max: f64,
    pub(super) post: Vec<f64>,
}

impl Blank {
    pub(super) fn new(plan: &Plan, vars: usize, classes: usize) -> Blank {
        let mut s = Scratch {
            slots: vec![0.0; vars * classes],
            ..Scratch::default()
        };
        let max = plan.up(&mut s, true);
        let ll = plan.up(&mut s, false);
        let mut post = vec![0.0; vars * classes];
        plan.down(&mut s, classes, &mut post);
        Blank { ll, max, post }
    }
}

/// A binary tree of partial sums over `m ≥ 1` log-values: leaves at `m..2m`, node `i`
/// holds `t[2i] + t[2i+1]`, the total at node 1 (node `m` when `m = 1`). Updating a
/// leaf recomputes its `O(log m)` ancestors from their children, never by subtracting.
#[derive(Clone, Debug)]
pub(super) struct SumTree {
    pub(super) t: Vec<f64>,
}

impl SumTree {
    pub(super) fn new(values: impl ExactSizeIterator<Item = f64>) -> SumTree {
        let m = values.len();
        let mut t = vec![0.0; 2 * m];
        for (k, v) in values.enumerate() {
            t[m + k] = v;
        }
        for i in (1..m).rev() {
            t[i] = t[2 * i] + t[2 * i + 1];
        }
        SumTree { t }
    }

    pub(super) fn total(&self) -> f64 {
        self.t[1]
    }

    pub(super) fn set(&mut self, k: usize, v: f64) {
        let m = self.t.len() / 2;
        let mut i = m + k;
        self.t[i] = v;
        while i > 1 {
            i /= 2;
            self.t[i] = self.t[2 * i] + self.t[2 * i + 1];
        }
    }
}
