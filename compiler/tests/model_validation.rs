//! The one template-SPN check shared by `Model::load` (infer, instance) and code
//! generation: malformed template SPNs are refused with the model file, the template
//! and the node named, by both paths alike; model weights are relative and rescaled
//! on loading.

use graphspn_compiler::codegen::{CodegenOptions, generate};
use graphspn_compiler::decompose::{DecompositionParams, decompose_best};
use graphspn_compiler::learn::{Model, ModelFileError, check_template_spn, normalise_weights};
use graphspn_compiler::map::TopoMap;
use graphspn_compiler::spn::{Node, Spn};

fn demo_text() -> String {
    std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../generated/demo/model.json"
    ))
    .unwrap()
}

fn demo_floor() -> TopoMap {
    TopoMap::load(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../generated/demo/floor.json"
    ))
    .unwrap()
}

/// A change to a model and a fragment of the message it must cause.
type Mutation = (fn(&mut Model), &'static str);

/// Singleton SPN (index 3) mutations: what to change and the fragments of the message.
fn mutations() -> Vec<Mutation> {
    vec![
        (|m| m.spns[3].root = 11, "root node 11"),
        (
            |m| {
                if let Node::Sum { children, .. } = &mut m.spns[3].nodes[10] {
                    children[9] = 99;
                }
            },
            "node 10: child 99",
        ),
        (
            |m| m.spns[3].nodes[0] = Node::Leaf { var: 3, class: 0 },
            "leaf node 0: variable 3",
        ),
        (
            |m| m.spns[3].nodes[3] = Node::Leaf { var: 0, class: 12 },
            "leaf node 3: class 12",
        ),
        (
            |m| {
                m.spns[3].nodes.push(Node::Leaf { var: 0, class: 0 });
                if let Node::Sum { children, .. } = &mut m.spns[3].nodes[10] {
                    children[0] = 11;
                }
            },
            "node 10: child 11",
        ),
        (
            |m| {
                if let Node::Sum { weights, .. } = &mut m.spns[3].nodes[10] {
                    weights.iter_mut().for_each(|w| *w = 0.0);
                }
            },
            "all weights are zero",
        ),
        (
            |m| {
                // A product over two leaves of the same variable under the root sum.
                m.spns[3].nodes.push(Node::Product {
                    children: vec![0, 1],
                });
                m.spns[3].nodes.push(Node::Sum {
                    children: vec![10, 11],
                    weights: vec![0.5, 0.5],
                });
                m.spns[3].root = 12;
            },
            "product node 11 is not decomposable",
        ),
    ]
}

#[test]
fn load_and_codegen_refuse_the_same_template_spns() {
    let text = demo_text();
    let good = Model::from_json(&text).unwrap();
    let map = demo_floor();
    let decs = decompose_best(&map, &good.templates, &DecompositionParams::default()).unwrap();
    for (mutate, fragment) in mutations() {
        let mut m = good.clone();
        mutate(&mut m);
        // Loading a file holding it names the file, the template and the node.
        let json = serde_json::to_string(&m).unwrap();
        let err = Model::from_json_named(&json, "bad-model.json").unwrap_err();
        assert!(
            matches!(&err, ModelFileError::TemplateSpn { template, index: 3, .. } if template == "singleton"),
            "{err}"
        );
        let msg = err.to_string();
        assert!(
            msg.starts_with("bad-model.json: template \"singleton\"") && msg.contains(fragment),
            "{msg}"
        );
        // Code generation from the same model in memory gives the same reason.
        let gen_err = generate(&m, &map, &decs, &CodegenOptions::default())
            .unwrap_err()
            .to_string();
        assert!(gen_err.contains(fragment), "{gen_err} lacks {fragment}");
    }
}

/// The weights of the demo singleton SPN's sum (node 10).
fn singleton_weights(spn: &mut Spn) -> &mut Vec<f64> {
    let Node::Sum { weights, .. } = &mut spn.nodes[10] else {
        panic!("node 10 is the singleton's sum")
    };
    weights
}

#[test]
fn weights_in_a_model_file_are_relative() {
    let text = demo_text();
    let good = Model::from_json(&text).unwrap();
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    let w = &mut v["spns"][3]["nodes"][10]["weights"];
    *w = serde_json::json!([1, 1, 1, 1, 1, 3, 1, 1, 1, 0]);
    let m = Model::from_json(&v.to_string()).unwrap();
    let Node::Sum { weights, .. } = &m.spns[3].nodes[10] else {
        panic!("node 10 is the singleton's sum")
    };
    let want: Vec<f64> = [1.0, 1.0, 1.0, 1.0, 1.0, 3.0, 1.0, 1.0, 1.0, 0.0]
        .iter()
        .map(|x| x / 11.0)
        .collect();
    assert_eq!(weights, &want);
    // Normalised weights are kept bit for bit: loading the demo changes nothing.
    let mut again = good.clone();
    for spn in &mut again.spns {
        assert_eq!(normalise_weights(spn), 0);
    }
    assert_eq!(again.spns, good.spns);
    // It counts the sums it rescales: one made relative here.
    let mut relative = good.spns[3].clone();
    singleton_weights(&mut relative)[5] *= 3.0;
    assert_eq!(normalise_weights(&mut relative), 1);
    // Weights whose sum overflows (or is subnormal) keep their ratios.
    for scale in [5e307, 1e-310] {
        let mut huge = good.spns[3].clone();
        let w = singleton_weights(&mut huge);
        w.iter_mut().for_each(|w| *w = 0.0);
        (w[0], w[1]) = (scale, 3.0 * scale);
        assert_eq!(normalise_weights(&mut huge), 1);
        let w = singleton_weights(&mut huge);
        assert!(
            (w[0] - 0.25).abs() < 1e-12 && (w[1] - 0.75).abs() < 1e-12,
            "{w:?}"
        );
        huge.validate().unwrap();
    }
    // A sum whose weights are all 0 (which the file check refuses) has nothing to
    // rescale by: it is left as it is, not divided by 0.
    let mut zero = good.spns[3].clone();
    singleton_weights(&mut zero)
        .iter_mut()
        .for_each(|w| *w = 0.0);
    assert_eq!(normalise_weights(&mut zero), 0);
    let weights = singleton_weights(&mut zero);
    assert!(weights.iter().all(|&w| w == 0.0), "{weights:?}");
    // And the instance SPN built from rescaled weights validates as normalised.
    m.spns[3].validate().unwrap();
}

/// The check's error names the SPN node it is about, where there is one.
#[test]
fn template_spn_errors_name_their_node() {
    let good = Model::from_json(&demo_text()).unwrap();
    let classes = good.classes.len();
    let mut bad = good.spns[3].clone();
    if let Node::Sum { children, .. } = &mut bad.nodes[10] {
        children[9] = 99;
    }
    let err = check_template_spn(&bad, 1, classes).unwrap_err();
    assert_eq!(err.node(), Some(10), "{err}");
    // A count mismatch is about the whole SPN.
    let err = check_template_spn(&good.spns[3], 2, classes).unwrap_err();
    assert_eq!(err.node(), None, "{err}");
    assert!(check_template_spn(&good.spns[3], 1, classes).is_ok());
}

/// A template's edges in a model file must be as the template defines them: sorted
/// `(a, b)` pairs with `a < b`. Reversed or reordered edges describe the same shape
/// but would pair the SPN's variables differently, so they are refused, naming it.
#[test]
fn template_edges_out_of_order_are_refused() {
    let good = Model::from_json(&demo_text()).unwrap();
    let reversed = |m: &mut Model| m.templates[2].edges = vec![(1, 0)];
    let reordered = |m: &mut Model| m.templates[1].edges = vec![(0, 2), (0, 1)];
    for (mutate, name) in [(reversed as fn(&mut Model), "pair"), (reordered, "three")] {
        let mut m = good.clone();
        mutate(&mut m);
        let json = serde_json::to_string(&m).unwrap();
        let Err(err) = Model::from_json_named(&json, "bad-model.json") else {
            panic!("{name}: edges out of order accepted");
        };
        let msg = err.to_string();
        assert!(
            msg.contains(&format!("template \"{name}\": edges must be sorted")),
            "{msg}"
        );
    }
}
