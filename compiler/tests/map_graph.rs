//! TopoMap construction, incremental growth, components and the JSON format.

use graphspn_compiler::map::synthetic::{SyntheticParams, generate};
use graphspn_compiler::map::{ClassSet, MapError, Place, TopoMap, cold};
use proptest::prelude::*;

fn place(id: u32, class: Option<u16>) -> Place {
    Place {
        id,
        class,
        placeholder: id.is_multiple_of(3),
        x: id as f64 * 0.8,
        y: -(id as f64) / 3.0,
    }
}

#[test]
fn new_sorts_places_and_dedupes_edges() {
    let places = vec![place(30, Some(1)), place(10, None), place(20, Some(0))];
    let m = TopoMap::new(
        "m",
        ClassSet::paper(),
        places,
        vec![(30, 10), (10, 30), (20, 30)],
    )
    .unwrap();
    let ids: Vec<u32> = m.places().map(|p| p.id).collect();
    assert_eq!(ids, vec![10, 20, 30]);
    assert_eq!(m.num_edges(), 2);
    assert_eq!(m.edge_list(), vec![(0, 2), (1, 2)]);
    assert_eq!(m.index_of_id(20), Some(1));
    assert_eq!(m.index_of_id(21), None);
    assert_eq!(m.degree(2), 2);
    assert!(m.has_edge(2, 0) && !m.has_edge(0, 1));
}

#[test]
fn growth_keeps_existing_indices() {
    let mut m = TopoMap::new(
        "m",
        ClassSet::paper(),
        vec![place(1, Some(1)), place(4, Some(1))],
        vec![(1, 4)],
    )
    .unwrap();
    let before: Vec<Place> = m.places().cloned().collect();
    assert_eq!(m.add_place(place(7, None)).unwrap(), 2);
    assert!(m.add_edge(4, 7).unwrap());
    assert!(!m.add_edge(7, 4).unwrap(), "no parallel edge");
    assert_eq!(m.num_edges(), 2);
    assert_eq!(m.place(0), &before[0]);
    assert_eq!(m.place(1), &before[1]);
    assert_eq!(m.index_of_id(7), Some(2));
    assert!(matches!(
        m.add_place(place(5, None)),
        Err(MapError::PlaceIdNotIncreasing { id: 5, max: 7 })
    ));
    assert!(matches!(
        m.add_place(place(7, None)),
        Err(MapError::DuplicatePlace { id: 7 })
    ));
    assert!(matches!(
        m.add_edge(7, 7),
        Err(MapError::SelfLoop { id: 7 })
    ));
    assert!(matches!(
        m.add_edge(7, 8),
        Err(MapError::MissingEndpoint { missing: 8, .. })
    ));
}

#[test]
fn components_and_largest() {
    let places = (0..7).map(|i| place(i, Some(1))).collect();
    let m = TopoMap::new(
        "m",
        ClassSet::paper(),
        places,
        vec![(0, 1), (2, 3), (3, 4), (4, 2), (5, 6)],
    )
    .unwrap();
    assert_eq!(
        m.connected_components(),
        vec![vec![0, 1], vec![2, 3, 4], vec![5, 6]]
    );
    let big = m.largest_component();
    let ids: Vec<u32> = big.places().map(|p| p.id).collect();
    assert_eq!(ids, vec![2, 3, 4]);
    assert_eq!(big.num_edges(), 3);
}

fn assert_same(a: &TopoMap, b: &TopoMap) {
    assert_eq!(a.name, b.name);
    assert_eq!(a.classes, b.classes);
    assert_eq!(
        a.places().collect::<Vec<_>>(),
        b.places().collect::<Vec<_>>()
    );
    assert_eq!(a.edge_list(), b.edge_list());
}

#[test]
fn json_round_trip_synthetic_and_file() {
    let m = generate(&SyntheticParams::new(300, 5)).unwrap();
    let text = m.to_json();
    assert!(
        text.starts_with("{\n  \"format\": 1,\n  \"name\""),
        "stable field order"
    );
    let back = TopoMap::from_json(&text).unwrap();
    assert_same(&m, &back);
    assert_eq!(back.to_json(), text, "byte-identical");
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("m.json");
    m.save(&path).unwrap();
    assert_same(&m, &TopoMap::load(&path).unwrap());
}

#[test]
fn json_round_trip_cold() {
    let dir = cold::data_dir(None);
    let m = cold::load_sequence(dir.join("Saarbrucken/seq3_cloudy1")).expect("load");
    assert_same(&m, &TopoMap::from_json(&m.to_json()).unwrap());
}

proptest! {
    #[test]
    fn json_round_trip_random(
        ids in proptest::collection::btree_set(0u32..1000, 1..20),
        raw_edges in proptest::collection::vec((0usize..20, 0usize..20), 0..40),
        xs in proptest::collection::vec(-1e6f64..1e6, 20),
    ) {
        let ids: Vec<u32> = ids.into_iter().collect();
        let places: Vec<Place> = ids.iter().enumerate().map(|(k, &id)| Place {
            id,
            class: if k % 4 == 0 { None } else { Some((k % 10) as u16) },
            placeholder: k % 2 == 0,
            x: xs[k],
            y: xs[19 - k] / 7.0,
        }).collect();
        let edges: Vec<(u32, u32)> = raw_edges.iter()
            .filter(|(a, b)| a != b && *a < ids.len() && *b < ids.len())
            .map(|&(a, b)| (ids[a], ids[b]))
            .collect();
        let m = TopoMap::new("p", ClassSet::paper(), places, edges).unwrap();
        let back = TopoMap::from_json(&m.to_json()).unwrap();
        prop_assert_eq!(m.places().collect::<Vec<_>>(), back.places().collect::<Vec<_>>());
        prop_assert_eq!(m.edge_list(), back.edge_list());
    }
}
