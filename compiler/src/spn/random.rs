//! Random valid SPNs for tests and fuzzing: complete, decomposable, normalised,
//! optionally selective, with shared sub-networks and some exact-zero weights.

use std::collections::HashMap;

use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::builder::SpnBuilder;
use super::{NodeId, Spn};

/// Knobs of [`random_spn`].
#[derive(Clone, Debug, PartialEq)]
pub struct RandomSpnParams {
    /// The SPN has `1..=max_vars` variables.
    pub max_vars: usize,
    /// Each variable has `1..=max_classes` classes (independently drawn).
    pub max_classes: u32,
    /// Maximum number of sum/product layers above the per-variable distributions.
    pub max_depth: usize,
    /// Maximum children of a sum or product (at least 2 is useful).
    pub max_children: usize,
    /// Probability that a sum weight is exactly 0 (each sum keeps one positive weight).
    pub zero_weight_prob: f64,
    /// Probability of reusing an existing node with the same scope and support
    /// (makes the SPN a DAG rather than a tree).
    pub share_prob: f64,
    /// Make every sum selective (deterministic): its children have disjoint supports.
    pub selective: bool,
}

impl Default for RandomSpnParams {
    fn default() -> Self {
        RandomSpnParams {
            max_vars: 6,
            max_classes: 4,
            max_depth: 4,
            max_children: 3,
            zero_weight_prob: 0.1,
            share_prob: 0.3,
            selective: false,
        }
    }
}

/// A random valid SPN ([`Spn::validate`] passes) from `seed`; same seed and params,
/// same SPN.
pub fn random_spn(seed: u64, params: &RandomSpnParams) -> Spn {
    random_spn_with_rng(&mut ChaCha8Rng::seed_from_u64(seed), params)
}

/// Like [`random_spn`], drawing from `rng`.
pub fn random_spn_with_rng<R: Rng>(rng: &mut R, params: &RandomSpnParams) -> Spn {
    let num_vars = rng.random_range(1..=params.max_vars.max(1));
    let classes: Vec<u32> = (0..num_vars)
        .map(|_| rng.random_range(1..=params.max_classes.max(1)))
        .collect();
    let allowed: Vec<Vec<u32>> = classes.iter().map(|&k| (0..k).collect()).collect();
    let scope: Vec<u32> = (0..num_vars as u32).collect();
    let mut g = Gen {
        rng,
        params,
        builder: SpnBuilder::new(classes),
        cache: HashMap::new(),
    };
    let depth = g.rng.random_range(0..=params.max_depth);
    let root = g.build(&scope, &allowed, depth);
    g.builder.finish_unchecked(root)
}

/// Scope variables and, for each, the classes its leaves may use.
type SupportKey = (Vec<u32>, Vec<Vec<u32>>);

struct Gen<'a, R: Rng> {
    rng: &'a mut R,
    params: &'a RandomSpnParams,
    builder: SpnBuilder,
    cache: HashMap<SupportKey, Vec<NodeId>>,
}

impl<R: Rng> Gen<'_, R> {
    fn weights(&mut self, n: usize) -> Vec<f64> {
        let mut w: Vec<f64> = (0..n)
            .map(|_| {
                if self
                    .rng
                    .random_bool(self.params.zero_weight_prob.clamp(0.0, 1.0))
                {
                    0.0
                } else {
                    self.rng.random_range(0.05..1.0)
                }
            })
            .collect();
        if w.iter().all(|&x| x == 0.0) {
            let i = self.rng.random_range(0..n);
            w[i] = self.rng.random_range(0.05..1.0);
        }
        let total: f64 = w.iter().sum();
        w.iter_mut().for_each(|x| *x /= total);
        w
    }

    fn num_children(&mut self, available: usize) -> usize {
        let hi = self.params.max_children.max(2).min(available);
        self.rng.random_range(2..=hi)
    }

    fn build(&mut self, scope: &[u32], allowed: &[Vec<u32>], depth: usize) -> NodeId {
        let key = (
            scope.to_vec(),
            scope.iter().map(|&v| allowed[v as usize].clone()).collect(),
        );
        if let Some(existing) = self.cache.get(&key)
            && self.rng.random_bool(self.params.share_prob.clamp(0.0, 1.0))
        {
            let i = self.rng.random_range(0..existing.len());
            return existing[i];
        }
        let id = self.build_new(scope, allowed, depth);
        self.cache.entry(key).or_default().push(id);
        id
    }

    fn leaf_distribution(&mut self, var: u32, allowed: &[u32]) -> NodeId {
        if allowed.len() == 1 {
            return self.builder.add_leaf(var, allowed[0]);
        }
        let children: Vec<NodeId> = allowed
            .iter()
            .map(|&c| self.builder.add_leaf(var, c))
            .collect();
        let w = self.weights(children.len());
        self.builder.add_sum(children, w)
    }

    fn build_new(&mut self, scope: &[u32], allowed: &[Vec<u32>], depth: usize) -> NodeId {
        let selective = self.params.selective;
        if depth == 0 {
            if scope.len() == 1 {
                return self.leaf_distribution(scope[0], &allowed[scope[0] as usize]);
            }
            let children: Vec<NodeId> = scope
                .iter()
                .map(|&v| self.leaf_distribution(v, &allowed[v as usize]))
                .collect();
            return self.builder.add_product(children);
        }
        let splittable: Vec<u32> = scope
            .iter()
            .copied()
            .filter(|&v| allowed[v as usize].len() >= 2)
            .collect();
        let can_product = scope.len() >= 2;
        let can_sum = !selective || !splittable.is_empty();
        let product = match (can_product, can_sum) {
            (true, true) => self.rng.random_bool(0.5),
            (true, false) => true,
            (false, true) => false,
            (false, false) => false,
        };
        if !product && !can_sum {
            return self.leaf_distribution(scope[0], &allowed[scope[0] as usize]);
        }
        if product {
            let mut vars = scope.to_vec();
            vars.shuffle(self.rng);
            let m = self.num_children(vars.len());
            // m non-empty groups: cut the shuffled list at m-1 distinct points.
            let mut cuts: Vec<usize> = (1..vars.len()).collect();
            cuts.shuffle(self.rng);
            let mut cuts: Vec<usize> = cuts[..m - 1].to_vec();
            cuts.sort_unstable();
            cuts.push(vars.len());
            let mut start = 0;
            let mut children = Vec::with_capacity(m);
            for end in cuts {
                let mut group = vars[start..end].to_vec();
                group.sort_unstable();
                children.push(self.build(&group, allowed, depth - 1));
                start = end;
            }
            return self.builder.add_product(children);
        }
        if scope.len() == 1 && !selective && self.rng.random_bool(0.5) {
            return self.leaf_distribution(scope[0], &allowed[scope[0] as usize]);
        }
        let children: Vec<NodeId> = if selective {
            let v = splittable[self.rng.random_range(0..splittable.len())];
            let mut classes = allowed[v as usize].clone();
            classes.shuffle(self.rng);
            let m = self.num_children(classes.len());
            let mut groups: Vec<Vec<u32>> = vec![Vec::new(); m];
            for (i, c) in classes.into_iter().enumerate() {
                let g = if i < m {
                    i
                } else {
                    self.rng.random_range(0..m)
                };
                groups[g].push(c);
            }
            groups
                .into_iter()
                .map(|mut g| {
                    g.sort_unstable();
                    let mut sub = allowed.to_vec();
                    sub[v as usize] = g;
                    self.build(scope, &sub, depth - 1)
                })
                .collect()
        } else {
            let m = self.num_children(usize::MAX);
            (0..m)
                .map(|_| self.build(scope, allowed, depth - 1))
                .collect()
        };
        let w = self.weights(children.len());
        self.builder.add_sum(children, w)
    }
}

/// A dense layered SPN for benchmarks and scaling tests (Poon–Domingos style over a
/// balanced binary split of the variables): every region holds `width` sums; a
/// single-variable region's sums mix that variable's `classes` leaves; a larger
/// region's sums mix all `width²` products of one sum from each half; the root mixes
/// the `width²` products of the top split. Weights are random (seeded) and
/// normalised. About `(num_vars − 1)·(width³ + 2·width²) + num_vars·width·classes` edges.
pub fn layered_spn(seed: u64, num_vars: usize, classes: u32, width: usize) -> Spn {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let num_vars = num_vars.max(1);
    let width = width.max(1);
    let mut b = SpnBuilder::new(vec![classes.max(1); num_vars]);
    let mut weights = |n: usize, rng: &mut ChaCha8Rng| -> Vec<f64> {
        let w: Vec<f64> = (0..n).map(|_| rng.random_range(0.01..1.0)).collect();
        let t: f64 = w.iter().sum();
        w.into_iter().map(|x| x / t).collect()
    };
    // Returns the region's sums, or (for the root region) the single root sum.
    fn region(
        b: &mut SpnBuilder,
        rng: &mut ChaCha8Rng,
        weights: &mut dyn FnMut(usize, &mut ChaCha8Rng) -> Vec<f64>,
        vars: std::ops::Range<u32>,
        width: usize,
        root: bool,
    ) -> Vec<NodeId> {
        let n_sums = if root { 1 } else { width };
        if vars.len() == 1 {
            let k = b.classes()[vars.start as usize];
            let leaves: Vec<NodeId> = (0..k).map(|c| b.add_leaf(vars.start, c)).collect();
            return (0..n_sums)
                .map(|_| {
                    let w = weights(leaves.len(), rng);
                    b.add_sum(leaves.clone(), w)
                })
                .collect();
        }
        let mid = vars.start + vars.len() as u32 / 2;
        let left = region(b, rng, weights, vars.start..mid, width, false);
        let right = region(b, rng, weights, mid..vars.end, width, false);
        let mut products = Vec::with_capacity(left.len() * right.len());
        for &l in &left {
            for &r in &right {
                products.push(b.add_product(vec![l, r]));
            }
        }
        (0..n_sums)
            .map(|_| {
                let w = weights(products.len(), rng);
                b.add_sum(products.clone(), w)
            })
            .collect()
    }
    let root = region(
        &mut b,
        &mut rng,
        &mut weights,
        0..num_vars as u32,
        width,
        true,
    )[0];
    b.finish_unchecked(root)
}
