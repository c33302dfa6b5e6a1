//! One test per structural error of `Spn::validate`, each checking the variant and
//! that the message names the offending node or variable; plus builder, normalise
//! and speed on a ~1M-edge SPN.

use graphspn_compiler::spn::random::layered_spn;
use graphspn_compiler::spn::{Node, Spn, SpnBuilder, SpnError};

fn leaf(var: u32, class: u32) -> Node {
    Node::Leaf { var, class }
}
fn sum(children: &[u32], weights: &[f64]) -> Node {
    Node::Sum {
        children: children.to_vec(),
        weights: weights.to_vec(),
    }
}
fn product(children: &[u32]) -> Node {
    Node::Product {
        children: children.to_vec(),
    }
}

/// P(Y0) · P(Y1), two binary variables; node 6 is the root.
fn base() -> Spn {
    Spn {
        classes: vec![2, 2],
        nodes: vec![
            leaf(0, 0),
            leaf(0, 1),
            leaf(1, 0),
            leaf(1, 1),
            sum(&[0, 1], &[0.5, 0.5]),
            sum(&[2, 3], &[0.3, 0.7]),
            product(&[4, 5]),
        ],
        root: 6,
    }
}

fn err(spn: &Spn) -> (SpnError, String) {
    let e = spn.validate().expect_err("expected an invalid SPN");
    let msg = e.to_string();
    (e, msg)
}

#[test]
fn base_is_valid() {
    base().validate().unwrap();
}

#[test]
fn no_variables() {
    let mut s = base();
    s.classes.clear();
    assert_eq!(err(&s).0, SpnError::NoVariables);
}

#[test]
fn zero_classes() {
    let mut s = base();
    s.classes[1] = 0;
    let (e, m) = err(&s);
    assert_eq!(e, SpnError::ZeroClasses { var: 1 });
    assert!(m.contains("variable 1"), "{m}");
}

#[test]
fn root_out_of_range() {
    let mut s = base();
    s.root = 7;
    let (e, m) = err(&s);
    assert_eq!(e, SpnError::RootOutOfRange { root: 7, len: 7 });
    assert!(m.contains("root node 7"), "{m}");
}

#[test]
fn child_out_of_range() {
    let mut s = base();
    s.nodes[6] = product(&[4, 9]);
    let (e, m) = err(&s);
    assert_eq!(
        e,
        SpnError::ChildOutOfRange {
            node: 6,
            child: 9,
            len: 7
        }
    );
    assert!(m.contains("node 6") && m.contains("child 9"), "{m}");
}

#[test]
fn weight_count_mismatch() {
    let mut s = base();
    s.nodes[4] = sum(&[0, 1], &[1.0]);
    let (e, m) = err(&s);
    assert!(matches!(
        e,
        SpnError::WeightCountMismatch {
            node: 4,
            children: 2,
            weights: 1
        }
    ));
    assert!(m.contains("sum node 4"), "{m}");
}

#[test]
fn empty_sum_and_product() {
    let mut s = base();
    s.nodes[5] = sum(&[], &[]);
    let (e, m) = err(&s);
    assert_eq!(e, SpnError::EmptySum { node: 5 });
    assert!(m.contains("sum node 5"), "{m}");
    let mut s = base();
    s.nodes[6] = product(&[]);
    let (e, m) = err(&s);
    assert_eq!(e, SpnError::EmptyProduct { node: 6 });
    assert!(m.contains("product node 6"), "{m}");
}

#[test]
fn non_finite_and_negative_weights() {
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        let mut s = base();
        s.nodes[4] = sum(&[0, 1], &[0.5, bad]);
        let (e, m) = err(&s);
        assert!(
            matches!(
                e,
                SpnError::NonFiniteWeight {
                    node: 4,
                    index: 1,
                    ..
                }
            ),
            "{e:?}"
        );
        assert!(m.contains("sum node 4") && m.contains("weight 1"), "{m}");
        assert!(s.normalise().is_err());
    }
    let mut s = base();
    s.nodes[5] = sum(&[2, 3], &[-0.5, 1.5]);
    let (e, m) = err(&s);
    assert!(matches!(
        e,
        SpnError::NegativeWeight {
            node: 5,
            index: 0,
            ..
        }
    ));
    assert!(m.contains("sum node 5") && m.contains("negative"), "{m}");
}

#[test]
fn unnormalised_weights_and_normalise() {
    let mut s = base();
    s.nodes[4] = sum(&[0, 1], &[0.5, 0.6]);
    let (e, m) = err(&s);
    assert!(matches!(e, SpnError::NotNormalised { node: 4, total } if (total - 1.1).abs() < 1e-12));
    assert!(m.contains("sum node 4"), "{m}");
    s.validate_unnormalised().unwrap();
    s.normalise().unwrap();
    s.validate().unwrap();
    let Node::Sum { weights, .. } = &s.nodes[4] else {
        panic!("node 4 is a sum")
    };
    assert!((weights[0] - 0.5 / 1.1).abs() < 1e-15 && (weights[1] - 0.6 / 1.1).abs() < 1e-15);
    // Within tolerance is accepted, beyond is not.
    let mut s = base();
    s.nodes[4] = sum(&[0, 1], &[0.5, 0.5 + 5e-10]);
    s.validate().unwrap();
    s.nodes[4] = sum(&[0, 1], &[0.5, 0.5 + 2e-9]);
    assert!(matches!(err(&s).0, SpnError::NotNormalised { node: 4, .. }));
}

#[test]
fn all_zero_weights() {
    let mut s = base();
    s.nodes[5] = sum(&[2, 3], &[0.0, 0.0]);
    assert_eq!(
        s.validate_unnormalised(),
        Err(SpnError::ZeroWeightSum { node: 5 })
    );
    let e = s.normalise().unwrap_err();
    assert_eq!(e, SpnError::ZeroWeightSum { node: 5 });
    assert!(e.to_string().contains("sum node 5"));
}

#[test]
fn leaf_out_of_range() {
    let mut s = base();
    s.nodes[2] = leaf(5, 0);
    let (e, m) = err(&s);
    assert_eq!(
        e,
        SpnError::LeafVarOutOfRange {
            node: 2,
            var: 5,
            num_vars: 2
        }
    );
    assert!(m.contains("leaf node 2") && m.contains("variable 5"), "{m}");
    let mut s = base();
    s.nodes[3] = leaf(1, 7);
    let (e, m) = err(&s);
    assert_eq!(
        e,
        SpnError::LeafClassOutOfRange {
            node: 3,
            var: 1,
            class: 7,
            classes: 2
        }
    );
    assert!(m.contains("leaf node 3") && m.contains("class 7"), "{m}");
}

#[test]
fn cycle_is_reported_as_cycle() {
    let mut s = base();
    // 4 → 6 → 4.
    s.nodes[4] = sum(&[0, 6], &[0.5, 0.5]);
    let (e, m) = err(&s);
    let SpnError::Cycle { nodes } = &e else {
        panic!("expected a cycle, got {e:?}")
    };
    let mut sorted = nodes.clone();
    sorted.sort_unstable();
    assert_eq!(sorted, vec![4, 6]);
    assert!(
        m.contains("cycle") && m.contains('4') && m.contains('6'),
        "{m}"
    );
    // A self-loop.
    let mut s = base();
    s.nodes[6] = product(&[4, 5, 6]);
    assert_eq!(err(&s).0, SpnError::Cycle { nodes: vec![6] });
}

#[test]
fn misordering_without_cycle() {
    let s = Spn {
        classes: vec![2],
        nodes: vec![sum(&[1, 2], &[0.5, 0.5]), leaf(0, 0), leaf(0, 1)],
        root: 0,
    };
    let (e, m) = err(&s);
    assert_eq!(e, SpnError::Misordered { node: 0, child: 1 });
    assert!(m.contains("node 0") && m.contains("child 1"), "{m}");
}

#[test]
fn incomplete_sum() {
    let s = Spn {
        classes: vec![2, 2],
        nodes: vec![leaf(0, 0), leaf(1, 0), sum(&[0, 1], &[0.5, 0.5])],
        root: 2,
    };
    let (e, m) = err(&s);
    assert_eq!(
        e,
        SpnError::Incomplete {
            node: 2,
            child_a: 0,
            scope_a: vec![0],
            child_b: 1,
            scope_b: vec![1]
        }
    );
    assert!(
        m.contains("sum node 2") && m.contains("[0]") && m.contains("[1]"),
        "{m}"
    );
}

#[test]
fn non_decomposable_product() {
    let s = Spn {
        classes: vec![2, 2],
        nodes: vec![leaf(0, 0), leaf(1, 0), product(&[0, 1]), product(&[2, 0])],
        root: 3,
    };
    let (e, m) = err(&s);
    assert_eq!(
        e,
        SpnError::NotDecomposable {
            node: 3,
            var: 0,
            child: 0
        }
    );
    assert!(
        m.contains("product node 3") && m.contains("variable 0"),
        "{m}"
    );
}

#[test]
fn variable_not_in_scope() {
    let mut s = base();
    s.classes.push(3);
    let (e, m) = err(&s);
    assert_eq!(e, SpnError::VariableNotInScope { var: 2 });
    assert!(m.contains("variable 2"), "{m}");
}

#[test]
fn unreachable_node() {
    let mut s = base();
    s.nodes.push(leaf(0, 0));
    s.nodes.push(leaf(1, 1));
    let (e, m) = err(&s);
    assert_eq!(
        e,
        SpnError::Unreachable {
            node: 7,
            root: 6,
            count: 2
        }
    );
    assert!(m.contains("node 7"), "{m}");
}

#[test]
fn builder_dedupes_leaves_and_validates() {
    let mut b = SpnBuilder::new(vec![2, 3]);
    let a0 = b.add_leaf(0, 0);
    let a1 = b.add_leaf(0, 1);
    assert_eq!(b.add_leaf(0, 0), a0);
    let sa = b.add_sum(vec![a0, a1], vec![1.0, 3.0]);
    let bs: Vec<u32> = (0..3).map(|c| b.add_leaf(1, c)).collect();
    let sb = b.add_sum(bs, vec![0.2, 0.3, 0.5]);
    let root = b.add_product(vec![sa, sb]);
    assert_eq!(b.len(), 8);
    let unnormalised = b.clone().finish(root);
    assert!(matches!(unnormalised, Err(SpnError::NotNormalised { node, .. }) if node == sa));
    let spn = b.finish_normalised(root).unwrap();
    assert_eq!(spn.num_edges(), 7);
    let Node::Sum { weights, .. } = &spn.nodes[sa as usize] else {
        panic!("sum")
    };
    assert_eq!(weights, &vec![0.25, 0.75]);
}

#[test]
fn validation_is_fast_on_a_million_edges() {
    let spn = layered_spn(7, 115, 10, 20);
    let edges = spn.num_edges();
    assert!(edges > 1_000_000, "{edges}");
    let t = std::time::Instant::now();
    spn.validate().unwrap();
    let dt = t.elapsed();
    eprintln!("validated {edges} edges in {dt:?}");
    assert!(dt.as_secs_f64() < 5.0, "validation took {dt:?}");
}
