//! The random SPN generator: valid for many seeds and parameters, deterministic,
//! selective when asked, and actually produces DAG sharing and exact-zero weights.

mod harness;

use graphspn_compiler::spn::random::{RandomSpnParams, layered_spn, random_spn};
use graphspn_compiler::spn::{Node, Spn};
use harness::all_assignments;

/// For one full assignment: does each node's support contain it (weights ignored)?
fn supports(spn: &Spn, x: &[u32]) -> Vec<bool> {
    let mut s = Vec::with_capacity(spn.nodes.len());
    for node in &spn.nodes {
        let v = match node {
            Node::Leaf { var, class } => x[*var as usize] == *class,
            Node::Sum { children, .. } => children.iter().any(|&c| s[c as usize]),
            Node::Product { children } => children.iter().all(|&c| s[c as usize]),
        };
        s.push(v);
    }
    s
}

#[test]
fn valid_for_many_seeds_and_params() {
    let mut params = vec![RandomSpnParams::default()];
    for selective in [false, true] {
        for (max_vars, max_classes, max_depth, max_children) in
            [(1, 1, 0, 2), (3, 2, 6, 4), (12, 10, 5, 3), (30, 3, 8, 5)]
        {
            params.push(RandomSpnParams {
                max_vars,
                max_classes,
                max_depth,
                max_children,
                zero_weight_prob: 0.2,
                share_prob: 0.5,
                selective,
            });
        }
    }
    for p in &params {
        for seed in 0..40 {
            let spn = random_spn(seed, p);
            if let Err(e) = spn.validate() {
                panic!("seed {seed}, params {p:?}: {e}\n{}", spn.to_json());
            }
        }
    }
}

#[test]
fn deterministic() {
    let p = RandomSpnParams::default();
    for seed in [0, 1, 12345, u64::MAX] {
        assert_eq!(
            random_spn(seed, &p).to_json(),
            random_spn(seed, &p).to_json()
        );
    }
    assert_ne!(random_spn(1, &p), random_spn(2, &p));
    assert_eq!(layered_spn(3, 9, 4, 3), layered_spn(3, 9, 4, 3));
}

#[test]
fn selective_sums_have_disjoint_supports() {
    let p = RandomSpnParams {
        selective: true,
        ..RandomSpnParams::default()
    };
    let mut multi_child_sums = 0;
    for seed in 0..60 {
        let spn = random_spn(seed, &p);
        for x in all_assignments(&spn.classes) {
            let s = supports(&spn, &x);
            for (id, node) in spn.nodes.iter().enumerate() {
                if let Node::Sum { children, .. } = node {
                    let on = children.iter().filter(|&&c| s[c as usize]).count();
                    assert!(
                        on <= 1,
                        "seed {seed}: sum {id} has {on} children supporting {x:?}"
                    );
                }
            }
        }
        multi_child_sums += spn
            .nodes
            .iter()
            .filter(|n| matches!(n, Node::Sum { children, .. } if children.len() > 1))
            .count();
    }
    assert!(multi_child_sums > 60);
}

#[test]
fn general_spns_have_sharing_zero_weights_and_non_selective_sums() {
    let p = RandomSpnParams::default();
    let (mut shared, mut zeros, mut non_selective) = (0, 0, 0);
    for seed in 0..60 {
        let spn = random_spn(seed, &p);
        let mut parents = vec![0u32; spn.nodes.len()];
        for node in &spn.nodes {
            match node {
                Node::Leaf { .. } => {}
                Node::Sum { children, weights } => {
                    zeros += weights.iter().filter(|&&w| w == 0.0).count();
                    children.iter().for_each(|&c| parents[c as usize] += 1);
                }
                Node::Product { children } => {
                    children.iter().for_each(|&c| parents[c as usize] += 1)
                }
            }
        }
        // Internal nodes with several parents (leaves are shared by deduplication anyway).
        shared += spn
            .nodes
            .iter()
            .zip(&parents)
            .filter(|(n, p)| !matches!(n, Node::Leaf { .. }) && **p > 1)
            .count();
        let selective_everywhere = all_assignments(&spn.classes).iter().all(|x| {
            let s = supports(&spn, x);
            spn.nodes.iter().all(|n| match n {
                Node::Sum { children, .. } => {
                    children.iter().filter(|&&c| s[c as usize]).count() <= 1
                }
                _ => true,
            })
        });
        non_selective += usize::from(!selective_everywhere);
    }
    assert!(shared > 0, "no shared internal node in 60 SPNs");
    assert!(zeros > 0, "no zero weight in 60 SPNs");
    assert!(
        non_selective > 10,
        "only {non_selective} non-selective SPNs"
    );
}

#[test]
fn layered_spn_size_formula() {
    // (vars − 1)·(w³ + 2w²) + vars·w·classes edges.
    let (v, k, w) = (9usize, 4u32, 3usize);
    let spn = layered_spn(1, v, k, w);
    spn.validate().unwrap();
    // The root region has a single sum over w² products: subtract the (w − 1)·w² edges it lacks.
    let expected = (v - 1) * (w * w * w + 2 * w * w) + v * w * k as usize - (w - 1) * w * w;
    assert_eq!(spn.num_edges(), expected);
}
