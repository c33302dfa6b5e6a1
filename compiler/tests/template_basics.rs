//! Templates: construction checks, automorphisms, the match check and the
//! rooted matchers (dedicated vs backtracking, against brute force).

use graphspn_compiler::decompose::synthetic::random_connected_map;
use graphspn_compiler::map::{ClassSet, Place, TopoMap};
use graphspn_compiler::template::{Adjacency, Matcher, Template, TemplateError};
use petgraph::graph::{NodeIndex, UnGraph};
use proptest::prelude::*;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

fn map_from_edges(n: usize, edges: &[(usize, usize)]) -> TopoMap {
    let mut g = UnGraph::<Place, ()>::new_undirected();
    for i in 0..n {
        g.add_node(Place {
            id: 100 + i as u32,
            class: None,
            placeholder: false,
            x: 0.0,
            y: 0.0,
        });
    }
    for &(a, b) in edges {
        g.add_edge(NodeIndex::new(a), NodeIndex::new(b), ());
    }
    TopoMap {
        name: "test".into(),
        classes: ClassSet::paper(),
        graph: g,
    }
}

fn triangle() -> Template {
    Template::custom("triangle", 3, &[(0, 1), (1, 2), (2, 0)]).unwrap()
}
fn path4() -> Template {
    Template::custom("path4", 4, &[(1, 0), (1, 2), (2, 3)]).unwrap()
}
fn square() -> Template {
    Template::custom("square", 4, &[(0, 1), (1, 2), (2, 3), (3, 0)]).unwrap()
}

/// Independent brute force: every injective map template → places with all
/// template edges on map edges and node 0 at `root`, avoiding `used`.
fn brute_force_matches(t: &Template, map: &TopoMap, root: usize, used: &[bool]) -> Vec<Vec<usize>> {
    let n = map.num_places();
    let mut out = Vec::new();
    let mut cur = vec![root];
    fn rec(
        t: &Template,
        map: &TopoMap,
        n: usize,
        used: &[bool],
        cur: &mut Vec<usize>,
        out: &mut Vec<Vec<usize>>,
    ) {
        let k = cur.len();
        if k == t.num_nodes {
            out.push(cur.clone());
            return;
        }
        for p in 0..n {
            if used[p] || cur.contains(&p) {
                continue;
            }
            // Every template edge whose later end is k: its earlier end is placed.
            let ok = t
                .edges
                .iter()
                .filter(|&&(a, b)| a.max(b) == k)
                .all(|&(a, b)| map.neighbors(cur[a.min(b)]).contains(&p));
            if ok {
                cur.push(p);
                rec(t, map, n, used, cur, out);
                cur.pop();
            }
        }
    }
    if !used[root] {
        rec(t, map, n, used, &mut cur, &mut out);
    }
    out
}

#[test]
fn custom_normalises_edges() {
    let t = Template::custom("t", 3, &[(2, 0), (1, 0)]).unwrap();
    assert_eq!(t.edges, vec![(0, 1), (0, 2)]);
    assert_eq!(
        t,
        Template {
            name: "t".into(),
            ..Template::three()
        }
    );
    for t in Template::paper_set() {
        t.validate().unwrap();
    }
}

#[test]
fn custom_rejects_bad_templates() {
    assert!(matches!(
        Template::custom("x", 0, &[]),
        Err(TemplateError::NoNodes { .. })
    ));
    assert!(matches!(
        Template::custom("", 1, &[]),
        Err(TemplateError::EmptyName)
    ));
    assert!(matches!(
        Template::custom("x", 2, &[(0, 2)]),
        Err(TemplateError::EdgeOutOfRange { a: 0, b: 2, .. })
    ));
    assert!(matches!(
        Template::custom("x", 2, &[(1, 1)]),
        Err(TemplateError::SelfLoop { node: 1, .. })
    ));
    assert!(matches!(
        Template::custom("x", 2, &[(0, 1), (1, 0)]),
        Err(TemplateError::DuplicateEdge { a: 0, b: 1, .. })
    ));
    assert!(matches!(
        Template::custom("x", 4, &[(0, 1), (2, 3)]),
        Err(TemplateError::Disconnected { .. })
    ));
    assert!(matches!(
        Template::custom("x", 9, &[]),
        Err(TemplateError::TooLarge { .. })
    ));
    let bad = Template {
        name: "raw".into(),
        num_nodes: 2,
        edges: vec![(1, 0)],
    };
    assert!(matches!(
        bad.validate(),
        Err(TemplateError::NotNormalised { .. })
    ));
    // Messages say which template.
    let msg = Template::custom("loopy", 2, &[(1, 1)])
        .unwrap_err()
        .to_string();
    assert!(msg.contains("loopy") && msg.contains('1'), "{msg}");
}

fn factorial(k: usize) -> usize {
    (1..=k).product()
}

#[test]
fn automorphism_groups() {
    let cases = [
        (Template::singleton(), 1),
        (Template::pair(), 2),
        (Template::three(), 2),
        (Template::star(), 24),
        (triangle(), 6),
        (path4(), 2),
        (square(), 8),
    ];
    for (t, expected) in cases {
        let auts = t.automorphisms();
        assert_eq!(auts.len(), expected, "{}", t.name);
        let identity: Vec<usize> = (0..t.num_nodes).collect();
        assert_eq!(auts[0], identity, "{}", t.name);
        assert!(
            auts.windows(2).all(|w| w[0] < w[1]),
            "{} not sorted",
            t.name
        );
        // Independently: each is a permutation mapping the edge set onto itself,
        // and every permutation that does so is listed (brute force over all n!).
        let edge_set = |perm: &[usize]| {
            let mut e: Vec<(usize, usize)> = t
                .edges
                .iter()
                .map(|&(a, b)| (perm[a].min(perm[b]), perm[a].max(perm[b])))
                .collect();
            e.sort();
            e
        };
        let mut count = 0;
        let mut perm = identity.clone();
        loop {
            if edge_set(&perm) == t.edges {
                count += 1;
                assert!(auts.contains(&perm), "{}: {perm:?} missing", t.name);
            }
            // next lexicographic permutation
            let n = perm.len();
            let Some(i) = (0..n.saturating_sub(1))
                .rev()
                .find(|&i| perm[i] < perm[i + 1])
            else {
                break;
            };
            let j = (i + 1..n).rev().find(|&j| perm[j] > perm[i]).unwrap();
            perm.swap(i, j);
            perm[i + 1..].reverse();
        }
        assert_eq!(count, auts.len(), "{}", t.name);
        assert!(count <= factorial(t.num_nodes));
    }
    // Three swaps A and B only.
    assert_eq!(Template::three().automorphisms()[1], vec![0, 2, 1]);
}

#[test]
fn match_check_is_a_monomorphism_check() {
    // Triangle 0-1-2 plus pendant 3 on 0.
    let map = map_from_edges(4, &[(0, 1), (1, 2), (2, 0), (0, 3)]);
    let three = Template::three();
    // Three with adjacent leaves (1, 2 are adjacent): still a match.
    assert!(three.is_isomorphic_to(&[0, 1, 2], &map));
    assert!(three.is_isomorphic_to(&[0, 1, 3], &map));
    // 3 is not adjacent to 1.
    assert!(!three.is_isomorphic_to(&[1, 0, 3], &map));
    let why = three.mismatch(&[1, 0, 3], &map).unwrap();
    assert!(why.contains("103") && why.contains("101"), "{why}");
    // Repeated place, wrong length, out of range.
    assert!(!three.is_isomorphic_to(&[0, 1, 1], &map));
    assert!(!three.is_isomorphic_to(&[0, 1], &map));
    assert!(!three.is_isomorphic_to(&[0, 1, 9], &map));
    assert!(triangle().is_isomorphic_to(&[2, 0, 1], &map));
    assert!(!triangle().is_isomorphic_to(&[0, 1, 3], &map));
}

#[test]
fn matchers_are_dedicated_for_stars_only() {
    for t in Template::paper_set() {
        assert!(Matcher::new(&t).unwrap().is_dedicated(), "{}", t.name);
        assert!(!Matcher::general(&t).unwrap().is_dedicated());
    }
    for t in [triangle(), path4(), square()] {
        assert!(!Matcher::new(&t).unwrap().is_dedicated(), "{}", t.name);
    }
    // A star rooted at a leaf is not star-shaped around node 0.
    let leaf_rooted = Template::custom("pair-leaf", 3, &[(0, 1), (1, 2)]).unwrap();
    assert!(!Matcher::new(&leaf_rooted).unwrap().is_dedicated());
}

#[test]
fn general_matcher_finds_non_induced_matches() {
    // K4: every Three has adjacent leaves; VF2's induced matching would fail.
    let map = map_from_edges(4, &[(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]);
    let adj = Adjacency::new(&map);
    let used = vec![false; 4];
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let mut out = Vec::new();
    for t in [Template::three(), path4(), square(), triangle()] {
        let m = Matcher::general(&t).unwrap();
        assert!(m.find_at(&adj, 0, &used, &mut rng, &mut out), "{}", t.name);
        assert!(t.is_isomorphic_to(&out, &map), "{}: {out:?}", t.name);
        assert_eq!(out[0], 0);
    }
}

fn all_templates() -> Vec<Template> {
    let mut v = Template::paper_set();
    v.extend([
        triangle(),
        path4(),
        square(),
        Template::custom("path4-mid", 4, &[(0, 1), (0, 2), (2, 3)]).unwrap(),
        Template::custom(
            "bowtie",
            5,
            &[(0, 1), (0, 2), (1, 2), (0, 3), (0, 4), (3, 4)],
        )
        .unwrap(),
    ]);
    v
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 128, ..ProptestConfig::default() })]

    /// On random graphs with random used sets, both matchers agree with brute
    /// force on whether a rooted match exists, and what they return is a match.
    #[test]
    fn matchers_agree_with_brute_force(
        n in 1usize..40,
        max_degree in 2usize..=8,
        extra in 0usize..60,
        seed in any::<u64>(),
        used_bits in any::<u64>(),
    ) {
        let map = random_connected_map(n, max_degree, extra, seed);
        let adj = Adjacency::new(&map);
        let used: Vec<bool> = (0..n).map(|i| (used_bits >> (i % 64)) & 1 == 1 && i % 3 != 0).collect();
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5eed);
        let mut out = Vec::new();
        for t in all_templates() {
            let fast = Matcher::new(&t).unwrap();
            let slow = Matcher::general(&t).unwrap();
            for root in 0..n {
                let expected = !brute_force_matches(&t, &map, root, &used).is_empty();
                prop_assert_eq!(fast.exists_at(&adj, root, &used), expected, "template {} root {} seed {}", &t.name, root, seed);
                prop_assert_eq!(slow.exists_at(&adj, root, &used), expected, "template {} root {} seed {}", &t.name, root, seed);
                for m in [&fast, &slow] {
                    let found = m.find_at(&adj, root, &used, &mut rng, &mut out);
                    prop_assert_eq!(found, expected);
                    if found {
                        prop_assert!(t.is_isomorphic_to(&out, &map), "{} {:?}", &t.name, &out);
                        prop_assert_eq!(out[0], root);
                        prop_assert!(out.iter().all(|&p| !used[p]));
                    }
                }
            }
        }
    }
}

/// The random choice covers every rooted match (on a small graph, many draws).
#[test]
fn random_matches_cover_all_rooted_matches() {
    let map = map_from_edges(6, &[(0, 1), (0, 2), (0, 3), (0, 4), (0, 5), (1, 2), (2, 3)]);
    let adj = Adjacency::new(&map);
    let used = vec![false; 6];
    for t in [Template::star(), Template::three(), path4()] {
        let all = brute_force_matches(&t, &map, 0, &used);
        for m in [Matcher::new(&t).unwrap(), Matcher::general(&t).unwrap()] {
            let mut rng = ChaCha8Rng::seed_from_u64(7);
            let mut seen = std::collections::BTreeSet::new();
            let mut out = Vec::new();
            for _ in 0..20_000 {
                assert!(m.find_at(&adj, 0, &used, &mut rng, &mut out));
                seen.insert(out.clone());
            }
            let all_set: std::collections::BTreeSet<_> = all.iter().cloned().collect();
            assert_eq!(seen, all_set, "{}", t.name);
        }
    }
}
