//! Shared helpers for the instance tests: small random models (dense random
//! structures or full tables with random weights), tiny maps, random evidence and a
//! brute-force template SPN evaluator.

use graphspn_compiler::decompose::synthetic::random_connected_map;
use graphspn_compiler::learn::model::MODEL_FORMAT;
use graphspn_compiler::learn::{DenseParams, Model, dense_structure};
use graphspn_compiler::map::{ClassSet, TopoMap};
use graphspn_compiler::spn::{Node, Spn};
use graphspn_compiler::template::Template;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A class set of `c` classes named `k0`, `k1`, ….
pub fn classes(c: usize) -> ClassSet {
    ClassSet::new((0..c).map(|k| format!("k{k}")).collect()).unwrap()
}

/// A random connected map of `n` places over `c` classes (no ground truth).
pub fn tiny_map(n: usize, c: usize, seed: u64) -> TopoMap {
    let mut m = random_connected_map(n, 4, 3, seed);
    m.classes = classes(c);
    m
}

fn randomise_weights(spn: &mut Spn, rng: &mut ChaCha8Rng) {
    for node in &mut spn.nodes {
        if let Node::Sum { weights, .. } = node {
            for w in weights.iter_mut() {
                *w = 0.05 + rng.random::<f64>();
            }
            let z: f64 = weights.iter().sum();
            weights.iter_mut().for_each(|w| *w /= z);
        }
    }
}

/// A full-table (selective) SPN over `n` variables of `c` classes: a sum over one
/// product of leaves per complete assignment, with random weights.
pub fn full_table(n: usize, c: u32, rng: &mut ChaCha8Rng) -> Spn {
    let mut nodes = Vec::new();
    for v in 0..n as u32 {
        for k in 0..c {
            nodes.push(Node::Leaf { var: v, class: k });
        }
    }
    let mut children = Vec::new();
    for x in all_labellings(n, c as u16) {
        if n == 1 {
            children.push(x[0] as u32);
        } else {
            nodes.push(Node::Product {
                children: x
                    .iter()
                    .enumerate()
                    .map(|(v, &k)| v as u32 * c + k as u32)
                    .collect(),
            });
            children.push((nodes.len() - 1) as u32);
        }
    }
    let weights = vec![1.0; children.len()];
    nodes.push(Node::Sum { children, weights });
    let mut spn = Spn {
        classes: vec![c; n],
        root: (nodes.len() - 1) as u32,
        nodes,
    };
    randomise_weights(&mut spn, rng);
    spn
}

/// A model over the paper's templates with `c` classes: full tables (selective) when
/// `selective`, else dense random structures; random weights either way.
pub fn random_model(c: usize, selective: bool, seed: u64) -> Model {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let templates = Template::paper_set();
    let spns = templates
        .iter()
        .map(|t| {
            if selective || t.num_nodes == 1 {
                full_table(t.num_nodes, c as u32, &mut rng)
            } else {
                let mut s =
                    dense_structure(t.num_nodes, c as u32, &DenseParams::default(), rng.random())
                        .unwrap();
                randomise_weights(&mut s, &mut rng);
                s
            }
        })
        .collect();
    Model {
        format: MODEL_FORMAT,
        family: Default::default(),
        classes: classes(c),
        templates,
        spns,
        settings: serde_json::Value::Null,
        trained_on: vec![],
    }
}

/// Random positive evidence rows (each row sums to 1).
pub fn random_rows(n: usize, c: usize, rng: &mut ChaCha8Rng) -> Vec<Vec<f64>> {
    (0..n)
        .map(|_| {
            let r: Vec<f64> = (0..c).map(|_| 0.05 + rng.random::<f64>()).collect();
            let z: f64 = r.iter().sum();
            r.into_iter().map(|x| x / z).collect()
        })
        .collect()
}

// The brute-force SPN evaluator and assignment enumerator shared with the learning tests.
#[allow(unused_imports)]
pub use super::learn::{all_labellings, value};
