//! The decomposition JSON file: round trip, determinism, and error messages.

use graphspn_compiler::decompose::file::{
    DecompositionFileError, FORMAT_VERSION, from_json, load, save, to_json,
};
use graphspn_compiler::decompose::synthetic::random_connected_map;
use graphspn_compiler::decompose::{DecomposeError, DecompositionParams, decompose_best};
use graphspn_compiler::map::TopoMap;
use graphspn_compiler::template::Template;

fn setup(
    seed: u64,
) -> (
    TopoMap,
    Vec<Template>,
    Vec<graphspn_compiler::decompose::Decomposition>,
) {
    let map = random_connected_map(60, 8, 90, seed);
    let ts = Template::paper_set();
    let ds = decompose_best(
        &map,
        &ts,
        &DecompositionParams {
            count: 3,
            candidates: 6,
            seed,
            ..DecompositionParams::default()
        },
    )
    .unwrap();
    (map, ts, ds)
}

#[test]
fn round_trip_by_names_and_ids() {
    for seed in 0..5 {
        let (map, ts, ds) = setup(seed);
        let text = to_json(&ds, &map, &ts).unwrap();
        assert_eq!(text, to_json(&ds, &map, &ts).unwrap(), "not deterministic");
        let v: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert_eq!(v["format"], FORMAT_VERSION);
        assert_eq!(v["map"], map.name.as_str());
        // Components are written with template names and place ids.
        let c0 = &v["decompositions"][0]["components"][0];
        let t0 = ds[0].components[0].template;
        assert_eq!(c0["template"], ts[t0].name.as_str());
        let ids: Vec<u64> = ds[0].components[0]
            .places
            .iter()
            .map(|&p| map.place(p).id as u64)
            .collect();
        assert_eq!(c0["places"], serde_json::json!(ids));
        assert_eq!(from_json(&text, &map, &ts).unwrap(), ds, "seed {seed}");
        // Read against a reordered template list: same components, new indices.
        let rev: Vec<Template> = ts.iter().rev().cloned().collect();
        let back = from_json(&text, &map, &rev).unwrap();
        for (a, b) in ds.iter().zip(&back) {
            for (ca, cb) in a.components.iter().zip(&b.components) {
                assert_eq!(ca.places, cb.places);
                assert_eq!(ts[ca.template].name, rev[cb.template].name);
            }
        }
    }
}

#[test]
fn save_and_load_files() {
    let (map, ts, ds) = setup(11);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("d.json");
    save(&path, &ds, &map, &ts).unwrap();
    assert_eq!(load(&path, &map, &ts).unwrap(), ds);
    let missing = dir.path().join("missing.json");
    let err = load(&missing, &map, &ts).unwrap_err();
    assert!(matches!(err, DecompositionFileError::Io { .. }));
    assert!(err.to_string().contains("missing.json"), "{err}");
    std::fs::write(&path, "{\n  \"format\": 1,\n  oops\n}").unwrap();
    let err = load(&path, &map, &ts).unwrap_err().to_string();
    assert!(err.contains("d.json") && err.contains("line 3"), "{err}");
}

fn err_of(text: &str, map: &TopoMap, ts: &[Template]) -> DecompositionFileError {
    from_json(text, map, ts).expect_err("should fail")
}

#[test]
fn errors_say_what_and_where() {
    let (map, ts, ds) = setup(5);
    let text = to_json(&ds, &map, &ts).unwrap();

    // Syntax error: line and column.
    let broken = text.replacen("\"components\"", "\"components\" :: ", 1);
    match err_of(&broken, &map, &ts) {
        DecompositionFileError::Syntax { line, column, .. } => {
            assert_eq!(line, 5);
            assert!(column > 1);
        }
        e => panic!("{e}"),
    }
    // Missing / unknown fields are reported with positions too.
    assert!(matches!(
        err_of("{\"format\": 1, \"map\": \"x\"}", &map, &ts),
        DecompositionFileError::Syntax { line: 1, .. }
    ));
    assert!(matches!(
        err_of(
            "{\"format\": 1, \"map\": \"x\", \"decompositions\": [], \"extra\": 0}",
            &map,
            &ts
        ),
        DecompositionFileError::Syntax { .. }
    ));
    // Version.
    let v2 = text.replacen("\"format\": 1", "\"format\": 2", 1);
    assert!(matches!(
        err_of(&v2, &map, &ts),
        DecompositionFileError::Format { found: 2 }
    ));
    // Map name.
    let other = text.replacen(
        &format!("\"map\": \"{}\"", map.name),
        "\"map\": \"elsewhere\"",
        1,
    );
    let e = err_of(&other, &map, &ts);
    assert!(matches!(e, DecompositionFileError::MapMismatch { .. }));
    assert!(e.to_string().contains("elsewhere"));
    // Unknown template name.
    let first_name = &ts[ds[0].components[0].template].name;
    let unk = text.replacen(
        &format!("\"template\": \"{first_name}\""),
        "\"template\": \"hexagon\"",
        1,
    );
    let e = err_of(&unk, &map, &ts);
    assert!(
        matches!(&e, DecompositionFileError::UnknownTemplateName { decomposition: 0, component: 0, name, .. } if name == "hexagon"),
        "{e}"
    );
    assert!(
        e.to_string().contains("hexagon") && e.to_string().contains("star"),
        "{e}"
    );

    // Build small files by hand for the place errors.
    let file = |components: &str| {
        format!(
            "{{\"format\": 1, \"map\": {}, \"decompositions\": [{{\"components\": [{components}]}}]}}",
            serde_json::to_string(&map.name).unwrap()
        )
    };
    let all_singletons: Vec<String> = map
        .places()
        .map(|p| format!("{{\"template\": \"singleton\", \"places\": [{}]}}", p.id))
        .collect();
    // All singletons is valid.
    let ok = from_json(&file(&all_singletons.join(",")), &map, &ts).unwrap();
    assert_eq!(ok[0].components.len(), map.num_places());
    // Unknown place id (ids are 10 + 3i, so 11 is not one).
    let mut bad = all_singletons.clone();
    bad[4] = "{\"template\": \"singleton\", \"places\": [11]}".into();
    let e = err_of(&file(&bad.join(",")), &map, &ts);
    assert!(
        matches!(
            e,
            DecompositionFileError::UnknownPlaceId {
                component: 4,
                id: 11,
                ..
            }
        ),
        "{e}"
    );
    // Place covered twice: names the place id.
    let mut bad = all_singletons.clone();
    bad.push(all_singletons[7].clone());
    let e = err_of(&file(&bad.join(",")), &map, &ts);
    let id7 = map.place(7).id;
    assert!(
        matches!(
            &e,
            DecompositionFileError::Invalid {
                source: DecomposeError::PlaceCoveredTwice { place: 7, .. },
                ..
            }
        ),
        "{e}"
    );
    assert!(e.to_string().contains(&format!("place id {id7}")), "{e}");
    // Place not covered.
    let mut bad = all_singletons.clone();
    bad.remove(9);
    let e = err_of(&file(&bad.join(",")), &map, &ts);
    assert!(
        matches!(
            &e,
            DecompositionFileError::Invalid {
                source: DecomposeError::PlaceNotCovered { place: 9, .. },
                ..
            }
        ),
        "{e}"
    );
    assert!(
        e.to_string()
            .contains(&format!("place id {}", map.place(9).id)),
        "{e}"
    );
    // Not a match: a pair of two non-adjacent places.
    let (a, b) = (0..map.num_places())
        .flat_map(|a| (0..map.num_places()).map(move |b| (a, b)))
        .find(|&(a, b)| a != b && !map.neighbors(a).contains(&b))
        .unwrap();
    let mut bad: Vec<String> = all_singletons
        .iter()
        .enumerate()
        .filter(|&(i, _)| i != a && i != b)
        .map(|(_, s)| s.clone())
        .collect();
    bad.push(format!(
        "{{\"template\": \"pair\", \"places\": [{}, {}]}}",
        map.place(a).id,
        map.place(b).id
    ));
    let e = err_of(&file(&bad.join(",")), &map, &ts);
    assert!(
        matches!(
            &e,
            DecompositionFileError::Invalid {
                source: DecomposeError::NotAMatch { .. },
                ..
            }
        ),
        "{e}"
    );
}

#[test]
fn writing_refuses_invalid_decompositions() {
    let (map, ts, mut ds) = setup(2);
    ds[1].components.pop();
    let e = to_json(&ds, &map, &ts).unwrap_err();
    assert!(
        matches!(
            e,
            DecompositionFileError::Invalid {
                decomposition: 1,
                ..
            }
        ),
        "{e}"
    );
}

#[test]
fn ambiguous_template_lists_are_refused() {
    let (map, ts, ds) = setup(3);
    let text = to_json(&ds, &map, &ts).unwrap();
    let mut dup = ts.clone();
    dup.push(Template::singleton());
    let e = from_json(&text, &map, &dup).unwrap_err();
    assert!(matches!(e, DecompositionFileError::Templates { .. }), "{e}");
    assert!(e.to_string().contains("singleton"), "{e}");
}
