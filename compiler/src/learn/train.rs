//! EM training of template SPNs on complete samples, and pruning.
//!
//! Samples are complete class tuples in the template's canonical variable order,
//! so every leaf is 0 or 1 and every pass is specialised for that. Identical
//! samples are merged first (with their multiplicity): the Star's ~360k augmented
//! samples have only a few thousand distinct tuples.
//!
//! **Update schedule.** Weights are re-estimated once per epoch from the counts
//! of all samples (full-batch EM). This is the exact EM step, so with fixed
//! smoothing the penalised objective never decreases (see
//! [`TrainingReport::objective_per_epoch`]), and the result does not depend on
//! sample order or batching. With only a few thousand distinct tuples a pass over
//! all of them costs milliseconds, so the per-batch updates the authors used to
//! bound memory buy nothing here. `batch_size` only sets the size of the work
//! chunks processed in parallel; chunk results are added in chunk order, so the
//! result is deterministic. Hard-EM counts are integers (exact in `f64`), so the
//! weights do not depend on `batch_size` at all; soft-EM expected counts may
//! differ in the last bits between batch sizes (never between runs).
//!
//! **Objective.** With smoothing `s`, an epoch maximises
//! `Σ_n log V_n(w) + s·Σ_e log w_e` over normalised weights, where `V_n` is the
//! value of the sample's max-product (MPE) tree (hard EM) or the SPN value (soft
//! EM). The M-step is `w_e ∝ count_e + s`.

use rayon::prelude::*;
use std::collections::BTreeMap;

use super::settings::{EmKind, TrainingSettings};
use super::symmetry::{EdgeOrbits, order_free_sum, set_normalised, sum_edge_offsets};
use crate::map::ClassId;
use crate::spn::{Node, NodeId, Spn};

// Shared with `symmetry` (sample checks), so it lives in `settings`, below both.
pub use super::settings::TrainError;

/// Progress reporting, shared by every long step ([`crate::progress`]).
pub use crate::progress::Progress;

/// What training did, per epoch. Log-likelihoods are natural logs, averaged over
/// the samples given (with multiplicity).
#[derive(Clone, Debug, PartialEq)]
pub struct TrainingReport {
    /// Mean log-likelihood per sample under the initial weights.
    pub initial_log_likelihood: f64,
    /// Mean log-likelihood per sample after each epoch's update.
    pub log_likelihood_per_epoch: Vec<f64>,
    /// Mean log-value of each sample's max-product (MPE) tree after each epoch.
    pub mpe_log_likelihood_per_epoch: Vec<f64>,
    /// The penalised objective after epoch `e`, with that epoch's smoothing,
    /// divided by the number of samples: `(Σ_n log V_n + s_e·Σ_e log w) / N` with
    /// `V_n` the MPE-tree value (hard) or SPN value (soft). Never decreases while
    /// the smoothing is fixed (up to rounding, ~1e-12 relative).
    pub objective_per_epoch: Vec<f64>,
    /// Smoothing used in each epoch.
    pub smoothing_per_epoch: Vec<f64>,
    /// Samples given.
    pub num_samples: usize,
    /// Distinct sample tuples.
    pub num_distinct: usize,
}

/// Flat form of an SPN for the training passes.
struct Flat {
    /// 0 = leaf, 1 = sum, 2 = product.
    kind: Vec<u8>,
    /// Leaf variable and class.
    leaf: Vec<(u32, u32)>,
    /// Children of node `i`: `children[start[i]..start[i+1]]`.
    start: Vec<usize>,
    children: Vec<u32>,
    /// For sums, offset of the node's edges in the flat sum-edge list.
    woff: Vec<usize>,
    root: usize,
}

impl Flat {
    fn new(spn: &Spn) -> Result<Self, TrainError> {
        let n = spn.nodes.len();
        if spn.root as usize >= n {
            return Err(TrainError::BadSpn {
                node: spn.root,
                what: format!("root out of range ({n} nodes)"),
            });
        }
        let woff = sum_edge_offsets(spn);
        let mut f = Flat {
            kind: Vec::with_capacity(n),
            leaf: Vec::with_capacity(n),
            start: Vec::with_capacity(n + 1),
            children: Vec::new(),
            woff,
            root: spn.root as usize,
        };
        for (id, node) in spn.nodes.iter().enumerate() {
            f.start.push(f.children.len());
            let bad = |what: String| TrainError::BadSpn {
                node: id as NodeId,
                what,
            };
            match node {
                Node::Leaf { var, class } => {
                    let classes = spn
                        .classes
                        .get(*var as usize)
                        .ok_or_else(|| bad(format!("leaf variable {var} out of range")))?;
                    if class >= classes {
                        return Err(bad(format!("leaf class {class} out of range")));
                    }
                    f.kind.push(0);
                    f.leaf.push((*var, *class));
                }
                Node::Sum { children, weights } => {
                    if children.is_empty() || children.len() != weights.len() {
                        return Err(bad("sum needs ≥ 1 child and one weight per child".into()));
                    }
                    f.kind.push(1);
                    f.leaf.push((0, 0));
                    f.children.extend_from_slice(children);
                }
                Node::Product { children } => {
                    if children.is_empty() {
                        return Err(bad("product without children".into()));
                    }
                    f.kind.push(2);
                    f.leaf.push((0, 0));
                    f.children.extend_from_slice(children);
                }
            }
            if let Some(&c) = f.children[f.start[id]..]
                .iter()
                .find(|&&c| c as usize >= id)
            {
                return Err(bad(format!("child {c} does not precede its parent")));
            }
        }
        f.start.push(f.children.len());
        Ok(f)
    }

    fn kids(&self, i: usize) -> &[u32] {
        &self.children[self.start[i]..self.start[i + 1]]
    }
}

/// Per-chunk E-step result.
struct Stats {
    counts: Vec<f64>,
    /// Per distinct sample: multiplicity × (log-likelihood, MPE log-value).
    ll: Vec<(f64, f64)>,
    zero: Option<usize>,
}

fn log_add(a: f64, b: f64) -> f64 {
    if a == f64::NEG_INFINITY {
        return b;
    }
    if b == f64::NEG_INFINITY {
        return a;
    }
    let (hi, lo) = if a > b { (a, b) } else { (b, a) };
    hi + (lo - hi).exp().ln_1p()
}

/// Scratch buffers of one worker.
struct Scratch {
    val: Vec<f64>,
    mval: Vec<f64>,
    best: Vec<u32>,
    mark: Vec<f64>,
}

impl Scratch {
    fn new(n: usize) -> Self {
        Scratch {
            val: vec![0.0; n],
            mval: vec![0.0; n],
            best: vec![0; n],
            mark: vec![0.0; n],
        }
    }
}

/// Upward pass on a complete sample: log SPN values into `s.val`, log
/// max-product values into `s.mval` and each sum's best child into `s.best`
/// (first maximum). Children of value zero are skipped (for complete data most
/// are). Returns (log-likelihood, log MPE-tree value).
fn up(f: &Flat, lw: &[f64], x: &[ClassId], s: &mut Scratch) -> (f64, f64) {
    for i in 0..f.kind.len() {
        let (v, mv) = match f.kind[i] {
            0 => {
                let (v, c) = f.leaf[i];
                let v = if u32::from(x[v as usize]) == c {
                    0.0
                } else {
                    f64::NEG_INFINITY
                };
                (v, v)
            }
            1 => {
                let off = f.woff[i];
                let kids = f.kids(i);
                let mut bv = f64::NEG_INFINITY;
                let mut bj = 0;
                let mut m = f64::NEG_INFINITY;
                for (j, &c) in kids.iter().enumerate() {
                    let vc = s.val[c as usize];
                    if vc == f64::NEG_INFINITY {
                        continue;
                    }
                    let w = lw[off + j];
                    let mv = w + s.mval[c as usize];
                    if mv > bv {
                        bv = mv;
                        bj = j;
                    }
                    m = m.max(w + vc);
                }
                s.best[i] = bj as u32;
                if m == f64::NEG_INFINITY {
                    (m, bv)
                } else {
                    let mut acc = 0.0;
                    for (j, &c) in kids.iter().enumerate() {
                        let vc = s.val[c as usize];
                        if vc != f64::NEG_INFINITY {
                            acc += (lw[off + j] + vc - m).exp();
                        }
                    }
                    (m + acc.ln(), bv)
                }
            }
            _ => {
                let (mut v, mut mv) = (0.0, 0.0);
                for &c in f.kids(i) {
                    v += s.val[c as usize];
                    mv += s.mval[c as usize];
                }
                (v, mv)
            }
        };
        s.val[i] = v;
        s.mval[i] = mv;
    }
    (s.val[f.root], s.mval[f.root])
}

/// Hard-EM counts: follow the MPE tree from the root (after [`up`]). Where children of
/// a sum tie for the best, the tree takes the first of them (lowest position).
fn hard_counts(f: &Flat, m: f64, s: &mut Scratch, counts: &mut [f64]) {
    s.mark.fill(0.0);
    s.mark[f.root] = 1.0;
    for i in (0..f.kind.len()).rev() {
        if s.mark[i] == 0.0 {
            continue;
        }
        match f.kind[i] {
            1 => {
                let j = s.best[i] as usize;
                counts[f.woff[i] + j] += m;
                s.mark[f.kids(i)[j] as usize] = 1.0;
            }
            2 => {
                for &c in f.kids(i) {
                    s.mark[c as usize] = 1.0;
                }
            }
            _ => {}
        }
    }
}

/// Soft-EM expected counts (after [`up`]): downward log-derivatives.
fn soft_counts(f: &Flat, lw: &[f64], m: f64, s: &mut Scratch, counts: &mut [f64]) {
    let root_val = s.val[f.root];
    s.mark.fill(f64::NEG_INFINITY);
    s.mark[f.root] = 0.0;
    for i in (0..f.kind.len()).rev() {
        let d = s.mark[i];
        if d == f64::NEG_INFINITY || s.val[i] == f64::NEG_INFINITY {
            continue;
        }
        match f.kind[i] {
            1 => {
                let off = f.woff[i];
                for (j, &c) in f.kids(i).iter().enumerate() {
                    let vc = s.val[c as usize];
                    if vc == f64::NEG_INFINITY {
                        continue;
                    }
                    counts[off + j] += m * (lw[off + j] + vc + d - root_val).exp();
                    s.mark[c as usize] = log_add(s.mark[c as usize], d + lw[off + j]);
                }
            }
            2 => {
                for &c in f.kids(i) {
                    let vc = s.val[c as usize];
                    s.mark[c as usize] = log_add(s.mark[c as usize], d + s.val[i] - vc);
                }
            }
            _ => {}
        }
    }
}

/// Merge identical samples: distinct tuples (sorted) with multiplicities.
pub fn dedupe(samples: &[Vec<ClassId>]) -> Vec<(Vec<ClassId>, u64)> {
    let mut map: BTreeMap<&[ClassId], u64> = BTreeMap::new();
    for s in samples {
        *map.entry(s.as_slice()).or_insert(0) += 1;
    }
    map.into_iter().map(|(k, v)| (k.to_vec(), v)).collect()
}

fn e_step(
    f: &Flat,
    lw: &[f64],
    data: &[(Vec<ClassId>, u64)],
    em: EmKind,
    want_counts: bool,
    chunk: usize,
    num_edges: usize,
) -> Totals {
    let parts: Vec<Stats> = data
        .par_chunks(chunk.max(1))
        .enumerate()
        .map(|(ci, part)| {
            let mut s = Scratch::new(f.kind.len());
            let mut st = Stats {
                counts: if want_counts {
                    vec![0.0; num_edges]
                } else {
                    Vec::new()
                },
                ll: Vec::with_capacity(part.len()),
                zero: None,
            };
            for (k, (x, m)) in part.iter().enumerate() {
                let m = *m as f64;
                let (ll, mpe) = up(f, lw, x, &mut s);
                if ll == f64::NEG_INFINITY {
                    st.zero.get_or_insert(ci * chunk + k);
                    continue;
                }
                if want_counts && em == EmKind::Soft {
                    soft_counts(f, lw, m, &mut s, &mut st.counts);
                }
                st.ll.push((m * ll, m * mpe));
                if want_counts && em == EmKind::Hard {
                    hard_counts(f, m, &mut s, &mut st.counts);
                }
            }
            st
        })
        .collect();
    let mut total = Totals {
        counts: vec![0.0; if want_counts { num_edges } else { 0 }],
        ll: 0.0,
        mpe_ll: 0.0,
        zero: None,
    };
    // Sample by sample in a fixed order, so the totals do not depend on chunking.
    for p in parts {
        for (t, c) in total.counts.iter_mut().zip(&p.counts) {
            *t += c;
        }
        for (ll, mpe) in p.ll {
            total.ll += ll;
            total.mpe_ll += mpe;
        }
        if total.zero.is_none() {
            total.zero = p.zero;
        }
    }
    total
}

/// E-step totals.
struct Totals {
    counts: Vec<f64>,
    ll: f64,
    mpe_ll: f64,
    zero: Option<usize>,
}

fn log_weights(spn: &Spn) -> Vec<f64> {
    let mut out = Vec::new();
    for n in &spn.nodes {
        if let Node::Sum { weights, .. } = n {
            out.extend(weights.iter().map(|w| w.ln()));
        }
    }
    out
}

fn check_samples(spn: &Spn, samples: &[Vec<ClassId>]) -> Result<(), TrainError> {
    if samples.is_empty() {
        return Err(TrainError::NoSamples);
    }
    let nv = spn.num_vars();
    for (index, s) in samples.iter().enumerate() {
        if s.len() != nv {
            return Err(TrainError::SampleLength {
                index,
                len: s.len(),
                num_vars: nv,
            });
        }
        for (var, (&class, &classes)) in s.iter().zip(&spn.classes).enumerate() {
            if u32::from(class) >= classes {
                return Err(TrainError::ClassOutOfRange {
                    index,
                    var,
                    class,
                    classes,
                });
            }
        }
    }
    Ok(())
}

/// Trains the sum weights of `spn` on complete samples with EM (hard or soft,
/// per `settings.em`), `settings.epochs` epochs, smoothing decaying linearly from
/// `smoothing_start` to `smoothing_end`; then prunes edges below
/// `settings.prune_threshold` (if > 0). Weights stay normalised. Deterministic.
pub fn train(
    spn: &mut Spn,
    samples: &[Vec<ClassId>],
    settings: &TrainingSettings,
    progress: Progress,
) -> Result<TrainingReport, TrainError> {
    let edges = sum_edge_offsets(spn)[spn.nodes.len()];
    train_tied(
        spn,
        samples,
        settings,
        &EdgeOrbits::trivial(edges),
        progress,
    )
}

/// [`train`] with the weights of each orbit of `orbits` kept equal (see
/// [`super::symmetry`]): the M-step gives every edge of an orbit the orbit's
/// mean count. Tied weights are bit-identical after every epoch.
pub fn train_tied(
    spn: &mut Spn,
    samples: &[Vec<ClassId>],
    settings: &TrainingSettings,
    orbits: &EdgeOrbits,
    progress: Progress,
) -> Result<TrainingReport, TrainError> {
    settings
        .check()
        .map_err(|e| TrainError::BadSettings(e.to_string()))?;
    check_samples(spn, samples)?;
    let flat = Flat::new(spn)?;
    let num_edges = flat.woff[spn.nodes.len()];
    if orbits.orbit_of.len() != num_edges {
        return Err(TrainError::OrbitMismatch {
            given: orbits.orbit_of.len(),
            actual: num_edges,
        });
    }
    for (id, n) in spn.nodes.iter().enumerate() {
        if let Node::Sum { weights, .. } = n
            && weights.iter().any(|w| !w.is_finite() || *w < 0.0)
        {
            return Err(TrainError::BadSpn {
                node: id as NodeId,
                what: "weights must be finite and ≥ 0".into(),
            });
        }
    }
    let data = dedupe(samples);
    let n_total = samples.len() as f64;
    let bar = progress.bar(settings.epochs as u64, "training");
    let mut report = TrainingReport {
        initial_log_likelihood: 0.0,
        log_likelihood_per_epoch: Vec::new(),
        mpe_log_likelihood_per_epoch: Vec::new(),
        objective_per_epoch: Vec::new(),
        smoothing_per_epoch: Vec::new(),
        num_samples: samples.len(),
        num_distinct: data.len(),
    };
    let zero_err = |k: usize| {
        let x = &data[k].0;
        TrainError::ZeroProbability {
            index: samples.iter().position(|s| s == x).unwrap_or(0),
            sample: x.clone(),
        }
    };
    let mut lw = log_weights(spn);
    let mut raw = vec![0.0; num_edges];
    for epoch in 0..=settings.epochs {
        let last = epoch == settings.epochs;
        let st = e_step(
            &flat,
            &lw,
            &data,
            settings.em,
            !last,
            settings.batch_size,
            num_edges,
        );
        if let Some(k) = st.zero {
            return Err(zero_err(k));
        }
        let ll = st.ll / n_total;
        let mpe = st.mpe_ll / n_total;
        if epoch == 0 {
            report.initial_log_likelihood = ll;
        } else {
            let s = settings.smoothing(epoch - 1);
            let fit = if settings.em == EmKind::Hard { mpe } else { ll };
            let penalty: f64 = lw.iter().sum();
            report.log_likelihood_per_epoch.push(ll);
            report.mpe_log_likelihood_per_epoch.push(mpe);
            report.objective_per_epoch.push(fit + s * penalty / n_total);
            bar.set_message(format!("log-likelihood/sample {ll:.4}"));
            bar.inc(1);
        }
        if last {
            break;
        }
        // M-step: w_e ∝ mean count over the orbit + s.
        let s = settings.smoothing(epoch);
        report.smoothing_per_epoch.push(s);
        for orbit in &orbits.orbits {
            let mut acc = 0.0;
            for &e in orbit {
                acc += st.counts[e as usize];
            }
            let v = acc / orbit.len() as f64 + s;
            for &e in orbit {
                raw[e as usize] = v;
            }
        }
        set_normalised(spn, &raw);
        lw = log_weights(spn);
    }
    bar.finish_and_clear();
    if settings.prune_threshold > 0.0 {
        prune(spn, settings.prune_threshold)?;
    }
    Ok(report)
}

/// Removes sum edges with weight below `threshold`, never all of a sum's
/// children (the heaviest ones stay), then drops nodes no longer reachable from
/// the root, renumbers (keeping topological order) and renormalises. Returns the
/// number of sum edges removed. Completeness and decomposability are kept: only
/// whole sum children are dropped. An SPN that training would refuse (a child that
/// does not precede its parent, a root out of range, ...) gives the same
/// [`TrainError::BadSpn`] and is left unchanged.
pub fn prune(spn: &mut Spn, threshold: f64) -> Result<usize, TrainError> {
    Flat::new(spn)?;
    let mut removed = 0;
    for n in &mut spn.nodes {
        if let Node::Sum { children, weights } = n {
            let max = weights.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let keep: Vec<bool> = weights
                .iter()
                .map(|&w| w >= threshold || w == max)
                .collect();
            let mut it = keep.iter();
            children.retain(|_| *it.next().unwrap_or(&true));
            let mut it = keep.iter();
            weights.retain(|_| *it.next().unwrap_or(&true));
            removed += keep.iter().filter(|k| !**k).count();
            let mut ws = weights.clone();
            let z = order_free_sum(&mut ws);
            for w in weights.iter_mut() {
                *w /= z;
            }
        }
    }
    // Reachability from the root.
    // Checked by `Flat::new`: the root is a node and every child precedes its parent.
    let n = spn.nodes.len();
    let mut live = vec![false; n];
    live[spn.root as usize] = true;
    for i in (0..n).rev() {
        if !live[i] {
            continue;
        }
        if let Node::Sum { children, .. } | Node::Product { children } = &spn.nodes[i] {
            for &c in children {
                live[c as usize] = true;
            }
        }
    }
    let mut new_id = vec![NodeId::MAX; n];
    let mut nodes = Vec::new();
    for (i, node) in std::mem::take(&mut spn.nodes).into_iter().enumerate() {
        if !live[i] {
            continue;
        }
        new_id[i] = nodes.len() as NodeId;
        let node = match node {
            Node::Sum { children, weights } => Node::Sum {
                children: children.iter().map(|&c| new_id[c as usize]).collect(),
                weights,
            },
            Node::Product { children } => Node::Product {
                children: children.iter().map(|&c| new_id[c as usize]).collect(),
            },
            leaf => leaf,
        };
        nodes.push(node);
    }
    spn.nodes = nodes;
    spn.root = new_id[spn.root as usize];
    Ok(removed)
}

/// Log-likelihood (natural log) of one complete sample under `spn`, by a direct
/// log-space upward pass (for tests and reports; the interpreter is the general
/// evaluator).
pub fn log_likelihood(spn: &Spn, sample: &[ClassId]) -> Result<f64, TrainError> {
    check_samples(spn, std::slice::from_ref(&sample.to_vec()))?;
    let f = Flat::new(spn)?;
    let lw = log_weights(spn);
    let mut s = Scratch::new(f.kind.len());
    Ok(up(&f, &lw, sample, &mut s).0)
}

/// Log-likelihoods (natural log) of many complete samples, one upward pass each.
pub fn log_likelihoods(spn: &Spn, samples: &[Vec<ClassId>]) -> Result<Vec<f64>, TrainError> {
    check_samples(spn, samples)?;
    let f = Flat::new(spn)?;
    let lw = log_weights(spn);
    let mut s = Scratch::new(f.kind.len());
    Ok(samples.iter().map(|x| up(&f, &lw, x, &mut s).0).collect())
}
