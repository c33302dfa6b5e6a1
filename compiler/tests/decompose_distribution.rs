//! The one-pass greedy stage has the distribution of the paper's loop
//! ("pick a uniformly random place where the template matches among the unused
//! places, take a random match there, repeat"): compared by simulation against
//! a direct implementation of that loop on small graphs.

use std::collections::BTreeMap;

use graphspn_compiler::decompose::decompose;
use graphspn_compiler::map::{ClassSet, Place, TopoMap};
use graphspn_compiler::template::{Adjacency, Matcher, Template};
use petgraph::graph::{NodeIndex, UnGraph};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn map_from_edges(n: usize, edges: &[(usize, usize)]) -> TopoMap {
    let mut g = UnGraph::<Place, ()>::new_undirected();
    for i in 0..n {
        g.add_node(Place {
            id: i as u32,
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
        name: "small".into(),
        classes: ClassSet::paper(),
        graph: g,
    }
}

/// A decomposition as a canonical key: sorted (template, sorted places).
type Key = Vec<(usize, Vec<usize>)>;

fn key(comps: impl IntoIterator<Item = (usize, Vec<usize>)>) -> Key {
    let mut k: Key = comps
        .into_iter()
        .map(|(t, mut p)| {
            p.sort();
            (t, p)
        })
        .collect();
    k.sort();
    k
}

/// The paper's loop, literally (templates already in decreasing size).
fn paper_loop(map: &TopoMap, templates: &[Template], rng: &mut ChaCha8Rng) -> Key {
    let adj = Adjacency::new(map);
    let n = map.num_places();
    let mut used = vec![false; n];
    let mut comps = Vec::new();
    let mut out = Vec::new();
    for (t, tpl) in templates.iter().enumerate() {
        let m = Matcher::new(tpl).unwrap();
        loop {
            let matchable: Vec<usize> = (0..n).filter(|&p| m.exists_at(&adj, p, &used)).collect();
            if matchable.is_empty() {
                break;
            }
            let root = matchable[rng.random_range(0..matchable.len())];
            assert!(m.find_at(&adj, root, &used, rng, &mut out));
            for &p in &out {
                used[p] = true;
            }
            comps.push((t, out.clone()));
        }
    }
    key(comps)
}

fn distribution(samples: impl Iterator<Item = Key>) -> BTreeMap<Key, f64> {
    let mut counts: BTreeMap<Key, f64> = BTreeMap::new();
    let mut total = 0.0;
    for k in samples {
        *counts.entry(k).or_default() += 1.0;
        total += 1.0;
    }
    counts.values_mut().for_each(|c| *c /= total);
    counts
}

fn total_variation(a: &BTreeMap<Key, f64>, b: &BTreeMap<Key, f64>) -> f64 {
    let keys: std::collections::BTreeSet<&Key> = a.keys().chain(b.keys()).collect();
    keys.into_iter()
        .map(|k| (a.get(k).unwrap_or(&0.0) - b.get(k).unwrap_or(&0.0)).abs())
        .sum::<f64>()
        / 2.0
}

#[test]
fn one_pass_matches_the_papers_loop() {
    let cases: Vec<(TopoMap, Vec<Template>)> = vec![
        // A path of 6 with a chord: pairs then singletons.
        (
            map_from_edges(6, &[(0, 1), (1, 2), (2, 3), (3, 4), (4, 5), (1, 4)]),
            vec![Template::pair(), Template::singleton()],
        ),
        // A small irregular graph: threes, pairs, singletons.
        (
            map_from_edges(
                7,
                &[
                    (0, 1),
                    (0, 2),
                    (0, 3),
                    (3, 4),
                    (4, 5),
                    (5, 6),
                    (2, 5),
                    (1, 2),
                ],
            ),
            vec![Template::three(), Template::pair(), Template::singleton()],
        ),
    ];
    let samples = 30_000;
    for (map, templates) in cases {
        let mut rng = ChaCha8Rng::seed_from_u64(2024);
        let ours = distribution((0..samples).map(|_| {
            let d = decompose(&map, &templates, &mut rng).unwrap();
            key(d.components.into_iter().map(|c| (c.template, c.places)))
        }));
        let mut rng = ChaCha8Rng::seed_from_u64(4048);
        let paper = distribution((0..samples).map(|_| paper_loop(&map, &templates, &mut rng)));
        let tv = total_variation(&ours, &paper);
        println!(
            "{} outcomes (ours) vs {} (paper loop), total variation {tv:.4}",
            ours.len(),
            paper.len()
        );
        assert!(ours.len() > 2, "test graph too trivial");
        // Sampling noise alone gives TV around sqrt(outcomes / samples) / 2 ≈ 0.01–0.02.
        assert!(tv < 0.04, "distributions differ: total variation {tv:.4}");
    }
}
