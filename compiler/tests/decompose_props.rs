//! Property tests of the decomposition (Alg. 2) over random connected graphs
//! (degrees up to 8, up to ~200 places). Proptest prints the failing
//! `(n, max_degree, extra, seed)`, which rebuilds the graph exactly.

use std::collections::BTreeSet;

use graphspn_compiler::decompose::synthetic::{grid_map, random_connected_map};
use graphspn_compiler::decompose::{
    DecomposeError, Decomposition, DecompositionParams, decompose, decompose_best,
};
use graphspn_compiler::map::TopoMap;
use graphspn_compiler::template::Template;
use proptest::prelude::*;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

fn triangle() -> Template {
    Template::custom("triangle", 3, &[(0, 1), (1, 2), (0, 2)]).unwrap()
}
fn path4() -> Template {
    Template::custom("path4", 4, &[(0, 1), (1, 2), (2, 3)]).unwrap()
}
fn square() -> Template {
    Template::custom("square", 4, &[(0, 1), (1, 2), (2, 3), (0, 3)]).unwrap()
}

/// Template lists to test with (each ends with a 1-node template).
fn template_sets() -> Vec<Vec<Template>> {
    vec![
        Template::paper_set(),
        vec![triangle(), Template::pair(), Template::singleton()],
        vec![Template::singleton(), path4(), Template::pair()],
        vec![square(), Template::three(), Template::singleton()],
        vec![
            Template::star(),
            square(),
            path4(),
            triangle(),
            Template::singleton(),
        ],
    ]
}

/// Independent check that `places` is a monomorphic image of `t` (uses only
/// `TopoMap::neighbors`, neither the matcher nor `Template::mismatch`).
fn independent_is_match(t: &Template, places: &[usize], map: &TopoMap) -> bool {
    places.len() == t.num_nodes
        && places.iter().collect::<BTreeSet<_>>().len() == places.len()
        && places.iter().all(|&p| p < map.num_places())
        && t.edges
            .iter()
            .all(|&(a, b)| map.neighbors(places[a]).contains(&places[b]))
}

/// Independent brute force: does `t` have a match among places in `free`?
fn exists_match_among(t: &Template, map: &TopoMap, free: &[bool]) -> bool {
    fn rec(t: &Template, map: &TopoMap, free: &[bool], cur: &mut Vec<usize>) -> bool {
        let k = cur.len();
        if k == t.num_nodes {
            return true;
        }
        // Candidates: if some earlier template neighbour is placed, only its
        // map neighbours; otherwise every free place.
        let earlier: Vec<usize> = t
            .edges
            .iter()
            .filter(|&&(a, b)| a.max(b) == k)
            .map(|&(a, b)| a.min(b))
            .collect();
        let cands: Vec<usize> = match earlier.first() {
            Some(&e) => map.neighbors(cur[e]),
            None => (0..map.num_places()).collect(),
        };
        for p in cands {
            if !free[p] || cur.contains(&p) {
                continue;
            }
            if earlier.iter().all(|&e| map.neighbors(cur[e]).contains(&p)) {
                cur.push(p);
                if rec(t, map, free, cur) {
                    return true;
                }
                cur.pop();
            }
        }
        false
    }
    rec(t, map, free, &mut Vec::new())
}

/// Template indices in decomposition order (nodes desc, edges desc, list order).
fn size_order(templates: &[Template]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..templates.len()).collect();
    order.sort_by_key(|&i| {
        (
            std::cmp::Reverse(templates[i].num_nodes),
            std::cmp::Reverse(templates[i].edges.len()),
            i,
        )
    });
    order
}

/// All properties of one decomposition, checked without the library's matcher.
fn check_decomposition(d: &Decomposition, map: &TopoMap, templates: &[Template], what: &str) {
    let n = map.num_places();
    // Partition of all places.
    let mut count = vec![0usize; n];
    for c in &d.components {
        for &p in &c.places {
            count[p] += 1;
        }
    }
    assert!(
        count.iter().all(|&k| k == 1),
        "{what}: not a partition: {count:?}"
    );
    // Every component a monomorphic image of its template.
    for c in &d.components {
        let t = &templates[c.template];
        assert!(
            independent_is_match(t, &c.places, map),
            "{what}: {c:?} is not a {}",
            t.name
        );
    }
    // Library validation agrees.
    d.validate(map, templates)
        .unwrap_or_else(|e| panic!("{what}: {e}"));
    // Maximality: for each template K (in size order), no K-match remains among
    // the places covered by templates that come after K.
    let order = size_order(templates);
    for (rank, &k) in order.iter().enumerate() {
        let later: BTreeSet<usize> = order[rank + 1..].iter().copied().collect();
        let free: Vec<bool> = {
            let mut f = vec![false; n];
            for c in &d.components {
                if later.contains(&c.template) {
                    for &p in &c.places {
                        f[p] = true;
                    }
                }
            }
            f
        };
        assert!(
            !exists_match_among(&templates[k], map, &free),
            "{what}: a {} match remains among places left for smaller templates",
            templates[k].name
        );
    }
    // Components come in size order of their templates.
    let rank_of = |t: usize| order.iter().position(|&o| o == t).unwrap();
    assert!(
        d.components
            .windows(2)
            .all(|w| rank_of(w[0].template) <= rank_of(w[1].template))
    );
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 128, ..ProptestConfig::default() })]

    #[test]
    fn decompositions_are_maximal_partitions_into_matches(
        n in 1usize..200,
        max_degree in 2usize..=8,
        extra_per_node in 0usize..4,
        seed in any::<u64>(),
    ) {
        let map = random_connected_map(n, max_degree, n * extra_per_node, seed);
        for (s, templates) in template_sets().iter().enumerate() {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let d = decompose(&map, templates, &mut rng).unwrap();
            check_decomposition(&d, &map, templates, &format!("set {s}, map {}", map.name));
            // Same seed, same decomposition.
            let mut rng2 = ChaCha8Rng::seed_from_u64(seed);
            prop_assert_eq!(&d, &decompose(&map, templates, &mut rng2).unwrap());
        }
    }

    #[test]
    fn best_of_n_is_sorted_valid_and_deterministic(
        n in 1usize..150,
        max_degree in 2usize..=8,
        extra_per_node in 0usize..3,
        seed in any::<u64>(),
        count in 1usize..6,
        more in 0usize..10,
    ) {
        let map = random_connected_map(n, max_degree, n * extra_per_node, seed);
        let templates = Template::paper_set();
        let params = DecompositionParams { count, candidates: count + more, seed, ..DecompositionParams::default() };
        let ds = decompose_best(&map, &templates, &params).unwrap();
        prop_assert_eq!(ds.len(), count);
        for (i, d) in ds.iter().enumerate() {
            check_decomposition(d, &map, &templates, &format!("best {i}, map {}", map.name));
        }
        let cov: Vec<usize> = ds.iter().map(|d| d.template_node_counts(4)[0]).collect();
        prop_assert!(cov.windows(2).all(|w| w[0] >= w[1]), "coverage not sorted: {:?}", cov);
        prop_assert_eq!(&ds, &decompose_best(&map, &templates, &params).unwrap());
        // The kept ones are the best: the worst kept beats or ties every
        // candidate, which we can't see directly; but with candidates == count
        // and a bigger candidate pool from the same seed, best coverage can only grow.
        let wider = DecompositionParams { candidates: count + more + 5, ..params };
        let ds2 = decompose_best(&map, &templates, &wider).unwrap();
        prop_assert!(ds2[0].template_node_counts(4)[0] >= cov[0]);
    }
}

#[test]
fn different_seeds_give_different_decompositions() {
    let map = random_connected_map(150, 8, 300, 42);
    let templates = Template::paper_set();
    let ds: BTreeSet<Vec<Vec<usize>>> = (0..10u64)
        .map(|seed| {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            decompose(&map, &templates, &mut rng)
                .unwrap()
                .components
                .into_iter()
                .map(|c| c.places)
                .collect()
        })
        .collect();
    assert!(
        ds.len() >= 9,
        "only {} distinct decompositions from 10 seeds",
        ds.len()
    );
    let a = decompose_best(
        &map,
        &templates,
        &DecompositionParams {
            seed: 1,
            ..Default::default()
        },
    )
    .unwrap();
    let b = decompose_best(
        &map,
        &templates,
        &DecompositionParams {
            seed: 2,
            ..Default::default()
        },
    )
    .unwrap();
    assert_ne!(a, b);
}

#[test]
fn custom_templates_tile_a_grid() {
    // An 8x8 4-neighbour grid tiles exactly by squares and by 4-paths, and a
    // triangle never matches (bipartite), so everything is pairs/singletons.
    let map = grid_map(8, 8, false);
    let sq = vec![square(), Template::singleton()];
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let d = decompose(&map, &sq, &mut rng).unwrap();
    check_decomposition(&d, &map, &sq, "squares on grid");
    assert!(d.template_node_counts(2)[0] > 0);
    let tri = vec![triangle(), Template::pair(), Template::singleton()];
    let d = decompose(&map, &tri, &mut rng).unwrap();
    check_decomposition(&d, &map, &tri, "triangles on grid");
    assert_eq!(d.template_node_counts(3)[0], 0);
    // With diagonals, triangles appear.
    let diag = grid_map(8, 8, true);
    let d = decompose(&diag, &tri, &mut rng).unwrap();
    check_decomposition(&d, &diag, &tri, "triangles on diagonal grid");
    assert!(d.template_node_counts(3)[0] > 0);
}

#[test]
fn bad_inputs_are_errors() {
    let map = random_connected_map(10, 4, 5, 0);
    let mut rng = ChaCha8Rng::seed_from_u64(0);
    assert!(matches!(
        decompose(&map, &[], &mut rng),
        Err(DecomposeError::NoTemplates)
    ));
    assert!(matches!(
        decompose(&map, &[Template::pair()], &mut rng),
        Err(DecomposeError::NoSingleton)
    ));
    assert!(matches!(
        decompose(
            &map,
            &[Template::singleton(), Template::singleton()],
            &mut rng
        ),
        Err(DecomposeError::DuplicateTemplateName { .. })
    ));
    let broken = Template {
        name: "broken".into(),
        num_nodes: 3,
        edges: vec![(0, 1)],
    };
    assert!(matches!(
        decompose(&map, &[broken, Template::singleton()], &mut rng),
        Err(DecomposeError::Template(_))
    ));
    let ts = Template::paper_set();
    for (count, candidates) in [(0, 5), (6, 5)] {
        let p = DecompositionParams {
            count,
            candidates,
            seed: 0,
            ..DecompositionParams::default()
        };
        assert!(matches!(
            decompose_best(&map, &ts, &p),
            Err(DecomposeError::BadParams(_))
        ));
    }
}

#[test]
fn validate_reports_what_is_wrong() {
    let map = random_connected_map(30, 6, 30, 9);
    let ts = Template::paper_set();
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let good = decompose(&map, &ts, &mut rng).unwrap();
    good.validate(&map, &ts).unwrap();
    let owner = good.component_of_place(30).unwrap();
    for (p, &c) in owner.iter().enumerate() {
        assert!(good.components[c].places.contains(&p));
    }
    let shares = good.template_shares(4);
    assert!((shares.iter().sum::<f64>() - 1.0).abs() < 1e-12);

    // Drop a component: its places are uncovered.
    let mut d = good.clone();
    let gone = d.components.remove(0);
    let err = d.validate(&map, &ts).unwrap_err();
    assert!(
        matches!(err, DecomposeError::PlaceNotCovered { .. }),
        "{err}"
    );
    let first_id = map.place(*gone.places.iter().min().unwrap()).id;
    assert!(
        err.to_string().contains(&format!("place id {first_id}")),
        "{err}"
    );
    // Duplicate a singleton of a covered place.
    let mut d = good.clone();
    d.components.push(graphspn_compiler::decompose::Component {
        template: 3,
        places: vec![0],
    });
    let err = d.validate(&map, &ts).unwrap_err();
    assert!(
        matches!(err, DecomposeError::PlaceCoveredTwice { place: 0, .. }),
        "{err}"
    );
    // A component that is not a match: relabel it as a template of another size.
    let mut d = good.clone();
    d.components[0].template = if d.components[0].template == 0 { 1 } else { 0 };
    assert!(matches!(
        d.validate(&map, &ts),
        Err(DecomposeError::NotAMatch { .. })
    ));
    let mut d = good;
    d.components[0].template = 7;
    assert!(matches!(
        d.validate(&map, &ts),
        Err(DecomposeError::UnknownTemplate { template: 7, .. })
    ));
}
