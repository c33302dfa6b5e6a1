//! The synthetic office-floor generator: size, determinism, geometry, and
//! statistics close to COLD's.

use graphspn_compiler::map::stats::MapStats;
use graphspn_compiler::map::synthetic::{SyntheticParams, generate};

#[test]
fn exact_size_connected_bounded_degree() {
    for (n, seed) in [(10, 0), (57, 1), (230, 2), (1000, 3), (20_000, 4)] {
        let m = generate(&SyntheticParams::new(n, seed)).unwrap();
        assert_eq!(m.num_places(), n);
        assert_eq!(m.connected_components().len(), 1, "n={n} seed={seed}");
        for i in 0..n {
            assert_eq!(m.place(i).id as usize, i, "ids are the exploration order");
            let d = m.degree(i);
            assert!(
                (1..=8).contains(&d),
                "n={n} seed={seed}: place {i} degree {d}"
            );
            assert!(m.place(i).class.is_some());
        }
        // Every prefix of the place order is connected (a robot's growing map).
        let prefix = m.induced_submap(&(0..n / 2).collect::<Vec<_>>());
        assert_eq!(prefix.connected_components().len(), 1);
    }
}

#[test]
fn neighbours_are_cold_like_distances_apart() {
    let m = generate(&SyntheticParams::new(3000, 11)).unwrap();
    let (mut orth, mut diag) = (0, 0);
    for (a, b) in m.edge_list() {
        let (p, q) = (m.place(a), m.place(b));
        let d = ((p.x - q.x).powi(2) + (p.y - q.y).powi(2)).sqrt();
        // Grid 0.8 m (orthogonal) or 1.13 m (diagonal), poses jittered by < 0.08 m per axis.
        assert!(
            (0.8 - 0.23..=1.132 + 0.23).contains(&d),
            "edge {a}-{b}: {d} m"
        );
        if d < 0.97 {
            orth += 1;
        } else {
            diag += 1;
        }
    }
    // COLD: 10,788 orthogonal vs 8,789 diagonal neighbour pairs; both kinds must be common.
    assert!(
        orth > diag / 2 && diag > orth / 3,
        "orth {orth} diag {diag}"
    );
}

#[test]
fn deterministic_in_seed() {
    let a = generate(&SyntheticParams::new(500, 42)).unwrap().to_json();
    let b = generate(&SyntheticParams::new(500, 42)).unwrap().to_json();
    let c = generate(&SyntheticParams::new(500, 43)).unwrap().to_json();
    assert_eq!(a, b);
    assert_ne!(a, c);
}

#[test]
fn rejects_bad_params() {
    for n in [0, 9, 100_001] {
        let e = generate(&SyntheticParams::new(n, 0))
            .unwrap_err()
            .to_string();
        assert!(e.contains(&n.to_string()), "{e}");
    }
    let mut p = SyntheticParams::new(100, 0);
    p.diagonal_keep = 1.5;
    assert!(
        generate(&p)
            .unwrap_err()
            .to_string()
            .contains("diagonal_keep")
    );
}

/// Synthetic maps should differ from pooled COLD no more than COLD's buildings
/// do. Between-building distances of the real data (pooled per building):
/// degree TV 0.07–0.13 (Freiburg–Saarbrucken 0.072, Stockholm–others 0.125,
/// 0.128), class TV 0.30–0.31 between buildings and 0.15–0.21 from the pooled
/// mix. We require degree TV < 0.13 and class TV < 0.21 from pooled COLD for
/// floors of 2,000 places over several seeds, plus plain range checks.
#[test]
fn statistics_close_to_cold() {
    let cold = MapStats::cold_reference();
    for seed in 0..5 {
        let m = generate(&SyntheticParams::new(2000, seed)).unwrap();
        let s = MapStats::of_map(&m);
        let dtv = s.degree_tv_distance(&cold);
        let ctv = s.class_tv_distance(&cold);
        assert!(dtv < 0.13, "seed {seed}: degree TV {dtv}");
        assert!(ctv < 0.21, "seed {seed}: class TV {ctv}");
        assert!(s.max_degree() <= 8);
        assert!(s.class_counts.iter().all(|&c| c > 0), "every class present");
        let cr = s.class_shares()[1];
        assert!(
            (0.25..=0.45).contains(&cr),
            "CR share {cr} (COLD 0.22-0.45 per building)"
        );
        let ph = s.placeholder_share();
        assert!(
            (0.15..=0.35).contains(&ph),
            "placeholder share {ph} (COLD 0.21-0.29)"
        );
        let epp = s.edges_per_place();
        assert!(
            (1.65..=2.05).contains(&epp),
            "edges/place {epp} (COLD 1.74-1.93)"
        );
    }
}
