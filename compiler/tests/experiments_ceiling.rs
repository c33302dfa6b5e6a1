//! The placeholder ceiling: an oracle that knows the explored places' classes and
//! labels each placeholder by the statistics of the training maps.

mod harness;

use graphspn_compiler::experiments::ceiling::placeholder_ceiling;
use graphspn_compiler::map::TopoMap;

/// A path `0 – 1 – 2` (classes `a`, `b`, `c`; place 2 a placeholder) plus, when
/// `extra` is given, a place 3 of that class hanging off place 1.
fn path(a: u16, b: u16, c: u16, extra: Option<u16>) -> TopoMap {
    let mut edges = vec![(0, 1), (1, 2)];
    let n = if extra.is_some() {
        edges.push((1, 3));
        4
    } else {
        3
    };
    let mut m = harness::codegen::map(n, 4, &edges);
    let classes = [Some(a), Some(b), Some(c), extra];
    for (i, w) in m.graph.node_weights_mut().enumerate() {
        w.class = classes[i];
        w.placeholder = i == 2;
    }
    m
}

#[test]
fn the_oracle_learns_what_follows_a_doorway_and_backs_off() {
    // Training: beyond a doorway (class 0) reached from a corridor (1) lies a room (2),
    // twice; once a corridor.
    let train = vec![
        path(1, 0, 2, None),
        path(1, 0, 2, None),
        path(1, 0, 1, None),
        // Beyond a doorway reached from a room (3) lies the corridor.
        path(3, 0, 1, None),
    ];
    // One hop sees only "next to a doorway": 2 rooms vs 2 corridors, tie → class 1.
    // Two hops sees which side the doorway was reached from.
    let test = vec![path(1, 0, 2, None), path(3, 0, 1, None)];
    let row = placeholder_ceiling("B", &train, &test);
    assert_eq!(row.placeholders, 2);
    assert_eq!(row.per_map.len(), 2);
    assert_eq!(
        row.per_map[0].one_hop, 0.0,
        "one hop: the tie goes to class 1"
    );
    assert_eq!(row.per_map[1].one_hop, 1.0);
    assert_eq!(row.two_hop, Some(1.0), "two hops tell the sides apart");
    assert_eq!(row.one_hop, Some(0.5));
    // An unseen two-hop context backs off to one hop.
    let unseen = vec![path(2, 0, 1, Some(3))];
    let row = placeholder_ceiling("B", &train, &unseen);
    assert_eq!(row.per_map[0].two_hop, row.per_map[0].one_hop);
    // Test maps without placeholders measure nothing: no accuracy, not 0%.
    let explored: Vec<_> = test
        .iter()
        .map(|m| {
            let mut m = m.clone();
            for w in m.graph.node_weights_mut() {
                w.placeholder = false;
            }
            m
        })
        .collect();
    let row = placeholder_ceiling("B", &train, &explored);
    assert_eq!(
        (row.placeholders, row.one_hop, row.two_hop),
        (0, None, None)
    );
}
