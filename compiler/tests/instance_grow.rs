//! Incremental growth of an instance: growing the map and calling `Instance::grow`
//! gives the same marginals as a full rebuild with the same decompositions, while
//! reusing the template copies of untouched components.

mod harness;

use std::collections::BTreeSet;

use graphspn_compiler::decompose::synthetic::random_connected_map;
use graphspn_compiler::instance::{Instance, InstanceError, InstanceModel, InstanceParams};
use graphspn_compiler::interpreter::Evidence;
use graphspn_compiler::map::TopoMap;
use harness::instance::{classes, random_model, random_rows};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

fn full_map(n: usize, seed: u64) -> TopoMap {
    let mut m = random_connected_map(n, 5, n / 4, seed);
    m.classes = classes(3);
    m
}

fn prefix(map: &TopoMap, k: usize) -> TopoMap {
    map.induced_submap(&(0..k).collect::<Vec<_>>())
}

fn assert_same_marginals(a: &Instance, b: &Instance, seed: u64) {
    let mut ma = InstanceModel::new(a.clone()).unwrap();
    let mut mb = InstanceModel::new(b.clone()).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    for _ in 0..3 {
        let ev = Evidence::from_rows(random_rows(a.num_places(), 3, &mut rng));
        let x = ma.marginals(&ev).unwrap();
        let y = mb.marginals(&ev).unwrap();
        assert!((x.log_likelihood - y.log_likelihood).abs() < 1e-9);
        for (r, s) in x.probs.iter().zip(&y.probs) {
            for (p, q) in r.iter().zip(s) {
                assert!((p - q).abs() < 1e-10, "{p} vs {q}");
            }
        }
    }
}

#[test]
fn grow_equals_rebuild_and_reuses_copies() {
    for seed in 0..4u64 {
        let model = random_model(3, seed % 2 == 0, seed);
        let full = full_map(40, seed);
        let mut inst = Instance::for_map(
            &model,
            &prefix(&full, 24),
            &InstanceParams {
                seed,
                ..InstanceParams::default()
            },
        )
        .unwrap();
        assert_eq!(inst.last_copy_stats().reused, 0);
        // Two exploration steps: 24 -> 32 -> 40 places.
        for (step, k) in [32usize, 40].into_iter().enumerate() {
            let before: BTreeSet<_> = inst
                .decompositions
                .iter()
                .flat_map(|d| d.components.iter().cloned())
                .collect();
            let grown = prefix(&full, k);
            let stats = inst.grow(&model, &grown, seed * 10 + step as u64).unwrap();
            for d in &inst.decompositions {
                d.validate(&grown, &model.templates).unwrap();
            }
            let after: BTreeSet<_> = inst
                .decompositions
                .iter()
                .flat_map(|d| d.components.iter().cloned())
                .collect();
            // Copies: every distinct component is either reused (it existed before) or
            // built, and the reused ones are exactly those kept from before.
            assert_eq!(stats.reused + stats.built, after.len());
            assert_eq!(stats.reused, after.intersection(&before).count());
            assert_eq!(inst.num_copies(), after.len());
            assert!(stats.reused > 0, "seed {seed}: nothing reused");
            assert!(stats.built > 0, "seed {seed}: nothing built");
            eprintln!(
                "seed {seed}, {k} places: {} copies reused, {} built",
                stats.reused, stats.built
            );
            let rebuilt = Instance::build(&model, &grown, inst.decompositions.clone()).unwrap();
            assert_eq!(rebuilt.spn.nodes.len(), inst.spn.nodes.len());
            assert_eq!(rebuilt.spn.num_edges(), inst.spn.num_edges());
            assert_same_marginals(&inst, &rebuilt, seed);
        }
    }
}

#[test]
fn untouched_components_are_kept() {
    let model = random_model(3, true, 7);
    let full = full_map(40, 7);
    let old = prefix(&full, 30);
    let mut inst = Instance::for_map(&model, &old, &InstanceParams::default()).unwrap();
    let old_decs = inst.decompositions.clone();
    inst.grow(&model, &full, 1).unwrap();
    let old_edges: BTreeSet<(usize, usize)> = old.edge_list().into_iter().collect();
    let touched: BTreeSet<usize> = full
        .edge_list()
        .into_iter()
        .filter(|e| !old_edges.contains(e) && !old_edges.contains(&(e.1, e.0)))
        .flat_map(|(a, b)| [a, b])
        .chain(30..40)
        .collect();
    for (od, nd) in old_decs.iter().zip(&inst.decompositions) {
        for comp in &od.components {
            let untouched = comp.places.iter().all(|p| !touched.contains(p));
            if untouched || model.templates[comp.template].num_nodes == 5 {
                assert!(nd.components.contains(comp), "{comp:?} was dropped");
            }
        }
    }
}

#[test]
fn grow_is_deterministic_and_rejects_shrinking() {
    let model = random_model(3, false, 3);
    let full = full_map(30, 3);
    let base = Instance::for_map(&model, &prefix(&full, 20), &InstanceParams::default()).unwrap();
    let mut a = base.clone();
    let mut b = base.clone();
    a.grow(&model, &full, 5).unwrap();
    b.grow(&model, &full, 5).unwrap();
    assert_eq!(a.decompositions, b.decompositions);
    assert_eq!(a.spn, b.spn);
    let mut c = a.clone();
    let err = c.grow(&model, &prefix(&full, 10), 5).unwrap_err();
    assert!(err.to_string().contains("only grow"), "{err}");
    let err = c
        .update(&model, &prefix(&full, 10), base.decompositions.clone())
        .unwrap_err();
    assert!(matches!(err, InstanceError::MapShrank { .. }) || err.to_string().contains("place"));
}
