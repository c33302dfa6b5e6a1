//! The explicit instance SPN of a tree mixture: the reference the interpreter
//! evaluates.
//!
//! Every forest is written in its *directed* form, with locally normalised weights
//! computed here from the model (an independent parameterisation from the shared
//! potential the fast evaluators use): the root of each tree draws its class from
//! `P_t(y_r)`, every other place from `P_t(y_v | y_parent)`, both derived from the
//! forest's messages without evidence. Nodes, per forest and place `v` in reverse
//! breadth-first order:
//!
//! - product `Π(v, b) = λ(v, b) · Π_{children c} Σ(c, b)` (the leaf alone for a leaf place);
//! - for a non-root place, per parent class `a`: sum `Σ(v, a) = Σ_b P_t(b | a) · Π(v, b)`;
//! - for a root: sum `R = Σ_b P_t(b) · Π(v, b)`; a forest's value is the product of its
//!   roots' sums;
//!
//! and the mixture root sums the forests with weight `1/T`. Leaves `λ(v, b)` are shared
//! by all forests. The SPN is complete, decomposable and normalised (its value
//! without evidence is 1). Its evidence is the tempered rows `α^γ` (the caller raises
//! the rows to the model's exponent). Size: about `T · places · (C² + 2C)` edges.

use super::TreeMixError;
use super::exact::TreeInstance;
use super::trees::NO_PARENT;
use crate::spn::{NodeId, Spn, SpnBuilder};

/// The explicit instance SPN of `instance` (its model and forests; its evidence is
/// not used). Variable `v` is place index `v`.
pub fn instance_spn(instance: &TreeInstance) -> Result<Spn, TreeMixError> {
    let c = instance.num_classes();
    let n = instance.num_places();
    let mut b = SpnBuilder::new(vec![c as u32; n]);
    let leaves: Vec<Vec<NodeId>> = (0..n)
        .map(|v| (0..c).map(|k| b.add_leaf(v as u32, k as u32)).collect())
        .collect();
    let mut forest_roots = Vec::new();
    for t in 0..instance.trees().len() {
        let forest = &instance.trees().forests[t];
        let children = forest.children();
        let (up, root_prior) = directed_weights(instance, t);
        // sums[v][a]: Σ(v, a) for a non-root place v.
        let mut sums: Vec<Vec<NodeId>> = vec![Vec::new(); n];
        let mut roots = Vec::new();
        for &v in forest.order.iter().rev() {
            let v = v as usize;
            let prods: Vec<NodeId> = (0..c)
                .map(|k| {
                    if children[v].is_empty() {
                        leaves[v][k]
                    } else {
                        let mut kids = vec![leaves[v][k]];
                        kids.extend(children[v].iter().map(|&ch| sums[ch as usize][k]));
                        b.add_product(kids)
                    }
                })
                .collect();
            if forest.parent[v] == NO_PARENT {
                roots.push(b.add_sum(prods, root_prior[v].clone()));
            } else {
                sums[v] = (0..c)
                    .map(|a| b.add_sum(prods.clone(), up[v][a].clone()))
                    .collect();
            }
        }
        forest_roots.push(if roots.len() == 1 {
            roots[0]
        } else {
            b.add_product(roots)
        });
    }
    let t = forest_roots.len();
    let root = if t == 1 {
        forest_roots[0]
    } else {
        b.add_sum(forest_roots, vec![1.0 / t as f64; t])
    };
    b.finish(root)
        .map_err(|e| TreeMixError::Model(format!("instance SPN: {e}")))
}

/// The directed form of forest `t`: `cond[v][a][b] = P_t(y_v = b | y_parent = a)` for
/// every non-root place and `prior[r][b] = P_t(y_r = b)` for every root, from the
/// upward messages without evidence (`m_v(a) = Σ_b ψ(a, b) u(b) Π_c m_c(b)`).
fn directed_weights(inst: &TreeInstance, t: usize) -> (Vec<Vec<Vec<f64>>>, Vec<Vec<f64>>) {
    let c = inst.num_classes();
    let n = inst.num_places();
    let (psi, unary) = inst.potentials();
    let forest = &inst.trees().forests[t];
    let children = forest.children();
    let mut msg = vec![Vec::new(); n];
    let mut cond = vec![Vec::new(); n];
    let mut prior = vec![Vec::new(); n];
    for &v in forest.order.iter().rev() {
        let v = v as usize;
        // g(b) = u(b) Π_c m_c(b), normalised.
        let mut g: Vec<f64> = unary.to_vec();
        for &ch in &children[v] {
            for (x, m) in g.iter_mut().zip(&msg[ch as usize]) {
                *x *= m;
            }
        }
        let s: f64 = g.iter().sum();
        g.iter_mut().for_each(|x| *x /= s);
        if forest.parent[v] == NO_PARENT {
            prior[v] = g;
        } else {
            let rows: Vec<Vec<f64>> = (0..c)
                .map(|a| {
                    let row: Vec<f64> = (0..c).map(|k| psi[a * c + k] * g[k]).collect();
                    let s: f64 = row.iter().sum();
                    row.into_iter().map(|x| x / s).collect()
                })
                .collect();
            let m: Vec<f64> = (0..c)
                .map(|a| (0..c).map(|k| psi[a * c + k] * g[k]).sum())
                .collect();
            let sm: f64 = m.iter().sum();
            msg[v] = m.into_iter().map(|x| x / sm).collect();
            cond[v] = rows;
        }
    }
    (cond, prior)
}
