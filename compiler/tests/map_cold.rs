//! Acceptance test of the COLD loader against the published statistics of the 90
//! maps (docs/FORMATS.md). Reads the shipped copy (or `$GRAPHSPN_DATA`); fails if missing.

use graphspn_compiler::map::{TopoMap, cold};

fn data_dir() -> std::path::PathBuf {
    let dir = cold::data_dir(None);
    assert!(dir.is_dir(), "{} is not a folder", dir.display());
    dir
}

/// Median as the reference table gives it (mean of the two middle values).
fn median(v: &mut [usize]) -> f64 {
    v.sort_unstable();
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2] as f64
    } else {
        (v[n / 2 - 1] + v[n / 2]) as f64 / 2.0
    }
}

/// (building, sequences, nodes min/median/max, edges min/median/max, placeholders)
type Row = (&'static str, usize, [f64; 3], [f64; 3], usize);

#[test]
fn cold_maps_match_reference_table() {
    let dir = data_dir();
    // (building, sequences, nodes min/median/max, edges min/median/max, placeholders)
    let table: [Row; 3] = [
        (
            "Freiburg",
            26,
            [81.0, 87.5, 154.0],
            [145.0, 162.5, 308.0],
            817,
        ),
        (
            "Saarbrucken",
            32,
            [46.0, 74.5, 230.0],
            [85.0, 140.0, 469.0],
            878,
        ),
        (
            "Stockholm",
            32,
            [115.0, 151.5, 191.0],
            [180.0, 255.5, 360.0],
            1041,
        ),
    ];
    let mut total = 0;
    for (building, count, nodes, edges, placeholders) in table {
        let maps = cold::load_building(&dir, building).expect("load building");
        assert_eq!(maps.len(), count, "{building}: sequence count");
        let mut n: Vec<usize> = maps.iter().map(TopoMap::num_places).collect();
        let mut e: Vec<usize> = maps.iter().map(TopoMap::num_edges).collect();
        let got_nodes = [
            *n.iter().min().unwrap() as f64,
            median(&mut n),
            *n.iter().max().unwrap() as f64,
        ];
        let got_edges = [
            *e.iter().min().unwrap() as f64,
            median(&mut e),
            *e.iter().max().unwrap() as f64,
        ];
        assert_eq!(got_nodes, nodes, "{building}: nodes min/median/max");
        assert_eq!(got_edges, edges, "{building}: edges min/median/max");
        let ph: usize = maps
            .iter()
            .map(|m| m.places().filter(|p| p.placeholder).count())
            .sum();
        assert_eq!(ph, placeholders, "{building}: placeholders");
        total += n.iter().sum::<usize>();
        for m in &maps {
            assert!(m.name.starts_with(&format!("{building}/")), "{}", m.name);
            assert_eq!(m.connected_components().len(), 1, "{} connected", m.name);
            for i in 0..m.num_places() {
                assert!(m.place(i).class.is_some());
                let d = m.degree(i);
                assert!((1..=8).contains(&d), "{}: degree {d}", m.name);
                if i > 0 {
                    assert!(
                        m.place(i - 1).id < m.place(i).id,
                        "place order sorted by id"
                    );
                }
            }
        }
        // Stable order: sorted by sequence name.
        let names: Vec<&str> = maps.iter().map(|m| m.name.as_str()).collect();
        let mut sorted = names.clone();
        sorted.sort();
        assert_eq!(names, sorted);
    }
    assert_eq!(total, 10_697);

    let all = cold::load_all(&dir).expect("load all");
    assert_eq!(all.len(), 90);
    assert!(all[0].name.starts_with("Freiburg/"));
    assert!(all[89].name.starts_with("Stockholm/"));
}

#[test]
fn cold_class_frequencies_and_relabel() {
    let dir = data_dir();
    let all = cold::load_all(&dir).expect("load all");
    let mut counts = [0usize; 10];
    for m in &all {
        for p in m.places() {
            counts[p.class.unwrap() as usize] += 1;
        }
    }
    let total: usize = counts.iter().sum();
    // Published class shares: CR 33.9%, 2PO 11.7%, 1PO 10.9%, ... (rounded to 0.1%).
    let expected = [5.3, 33.9, 10.9, 11.7, 3.8, 10.2, 4.9, 5.5, 5.1, 8.7];
    for (c, &e) in expected.iter().enumerate() {
        let got = 100.0 * counts[c] as f64 / total as f64;
        assert!((got - e).abs() <= 0.051, "class {c}: {got:.2}% vs {e}%");
    }
    // The relabelled room 7-2PO-1 → 1PO: a Stockholm floor-7 sequence whose
    // nodes.dat says 2PO for those nodes now has them as 1PO.
    let seq = dir.join("Stockholm/floor7_cloudy_a1");
    let rooms = std::fs::read_to_string(seq.join("rooms.dat")).unwrap();
    let relabelled: Vec<u32> = rooms
        .lines()
        .filter_map(|l| {
            let mut it = l.split_whitespace();
            let id = it.next()?.parse().ok()?;
            (it.next()? == "7-2PO-1").then_some(id)
        })
        .collect();
    assert!(!relabelled.is_empty(), "floor7_cloudy_a1 has room 7-2PO-1");
    let m = cold::load_sequence(&seq).unwrap();
    let mut checked = 0;
    for id in relabelled {
        if let Some(i) = m.index_of_id(id) {
            assert_eq!(m.place(i).class, Some(2), "node {id} should be 1PO");
            checked += 1;
        }
    }
    assert!(checked > 0);
}

#[test]
fn cold_reference_stats_match_data() {
    use graphspn_compiler::map::stats::MapStats;
    let dir = data_dir();
    let all = cold::load_all(&dir).expect("load all");
    assert_eq!(MapStats::of_maps(&all), MapStats::cold_reference());
}

/// A sequence is named `building/sequence` however its folder is spelled: with `.`
/// and `..` in the path, or through a path that ends in `.`.
#[test]
fn a_sequence_is_named_the_same_however_its_path_is_spelled() {
    let dir = data_dir();
    let plain = cold::load_sequence(dir.join("Freiburg/seq1_cloudy1")).unwrap();
    assert_eq!(plain.name, "Freiburg/seq1_cloudy1");
    for spelled in [
        dir.join("Freiburg/seq1_cloudy1/."),
        dir.join("Freiburg/seq1_cloudy2/../seq1_cloudy1"),
        dir.join("Saarbrucken/../Freiburg/./seq1_cloudy1"),
    ] {
        let m = cold::load_sequence(&spelled).unwrap();
        assert_eq!(m.name, plain.name, "{}", spelled.display());
    }
}
