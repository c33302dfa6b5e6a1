//! Shared helpers for the learning tests: automorphism groups, a brute-force
//! SPN evaluator (independent of the training passes) and a synthetic sampler.

use graphspn_compiler::map::ClassId;
use graphspn_compiler::spn::{Node, Spn};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::SeedableRng;

pub use super::permutations;

/// One variable of two classes, one sum over its two indicator leaves with `weights`:
/// the smallest SPN, and a selective one (a complete sample reaches one child).
pub fn indicator_sum(weights: Vec<f64>) -> Spn {
    Spn {
        classes: vec![2],
        nodes: vec![
            Node::Leaf { var: 0, class: 0 },
            Node::Leaf { var: 0, class: 1 },
            Node::Sum {
                children: vec![0, 1],
                weights,
            },
        ],
        root: 2,
    }
}

/// Automorphisms of Pair (P–A): identity and the swap.
pub fn pair_group() -> Vec<Vec<usize>> {
    vec![vec![0, 1], vec![1, 0]]
}

/// Automorphisms of Three (A–P–B, order [P, A, B]).
pub fn three_group() -> Vec<Vec<usize>> {
    vec![vec![0, 1, 2], vec![0, 2, 1]]
}

/// Automorphisms of Star (order [P, A, B, C, D]): P fixed, leaves permuted (24).
pub fn star_group() -> Vec<Vec<usize>> {
    permutations(&[1, 2, 3, 4])
        .into_iter()
        .map(|p| {
            let mut v = vec![0];
            v.extend(p);
            v
        })
        .collect()
}

/// Linear-space value of the SPN for a complete assignment, by plain recursion
/// over the node list (an oracle independent of `learn::train`).
pub fn value(spn: &Spn, x: &[ClassId]) -> f64 {
    node_values(spn, x)[spn.root as usize]
}

/// Linear-space value of every node of the SPN for a complete assignment (see
/// [`value`]).
pub fn node_values(spn: &Spn, x: &[ClassId]) -> Vec<f64> {
    let mut v = vec![0.0f64; spn.nodes.len()];
    for (i, n) in spn.nodes.iter().enumerate() {
        v[i] = match n {
            Node::Leaf { var, class } => f64::from(u8::from(u32::from(x[*var as usize]) == *class)),
            Node::Sum { children, weights } => children
                .iter()
                .zip(weights)
                .map(|(&c, w)| w * v[c as usize])
                .sum(),
            Node::Product { children } => children.iter().map(|&c| v[c as usize]).product(),
        };
    }
    v
}

/// All assignments of `n` variables with `c` classes each, as class ids (the first
/// variable slowest; [`super::all_assignments`] with equal class counts).
pub fn all_labellings(n: usize, c: u16) -> Vec<Vec<ClassId>> {
    super::all_assignments(&vec![u32::from(c); n])
        .into_iter()
        .map(|x| x.into_iter().map(|k| k as ClassId).collect())
        .collect()
}

/// A structured random distribution over `n` variables with `c` classes: a
/// mixture of `k` product distributions with peaked factors. Returns the full
/// joint table (index = mixed radix, variable 0 most significant).
pub fn mixture_table(n: usize, c: u16, k: usize, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mix: Vec<f64> = (0..k).map(|_| 0.2 + rng.random::<f64>()).collect();
    let zm: f64 = mix.iter().sum();
    let factors: Vec<Vec<Vec<f64>>> = (0..k)
        .map(|_| {
            (0..n)
                .map(|_| {
                    let f: Vec<f64> = (0..c).map(|_| rng.random::<f64>().powi(4) + 0.01).collect();
                    let z: f64 = f.iter().sum();
                    f.into_iter().map(|x| x / z).collect()
                })
                .collect()
        })
        .collect();
    all_labellings(n, c)
        .iter()
        .map(|x| {
            (0..k)
                .map(|j| {
                    mix[j] / zm
                        * x.iter()
                            .enumerate()
                            .map(|(i, &xi)| factors[j][i][xi as usize])
                            .product::<f64>()
                })
                .sum()
        })
        .collect()
}

/// Index of an assignment in a table from [`mixture_table`].
pub fn index_of(x: &[ClassId], c: u16) -> usize {
    x.iter().fold(0, |acc, &v| acc * c as usize + v as usize)
}

/// `m` samples from a joint table (seeded).
pub fn sample_table(table: &[f64], n: usize, c: u16, m: usize, seed: u64) -> Vec<Vec<ClassId>> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let assignments = all_labellings(n, c);
    let mut cdf = Vec::with_capacity(table.len());
    let mut acc = 0.0;
    for p in table {
        acc += p;
        cdf.push(acc);
    }
    (0..m)
        .map(|_| {
            let u = rng.random::<f64>() * acc;
            let i = cdf.partition_point(|&x| x < u).min(table.len() - 1);
            assignments[i].clone()
        })
        .collect()
}
