//! SVG rendering: well-formed XML with one place group per place, legends,
//! placeholders, pies, decomposition colouring and highlights.

use graphspn_compiler::decompose::{Component, Decomposition};
use graphspn_compiler::map::synthetic::{SyntheticParams, generate};
use graphspn_compiler::map::{TopoMap, cold};
use graphspn_compiler::render::{RenderError, RenderOptions, check_options, render_svg};
use graphspn_compiler::template::Template;

fn has_class(n: &roxmltree::Node, c: &str) -> bool {
    n.attribute("class")
        .is_some_and(|a| a.split_whitespace().any(|w| w == c))
}

fn count_class(doc: &roxmltree::Document, c: &str) -> usize {
    doc.descendants().filter(|n| has_class(n, c)).count()
}

fn texts(doc: &roxmltree::Document) -> Vec<String> {
    doc.descendants()
        .filter(|n| n.has_tag_name("text"))
        .filter_map(|n| n.text().map(str::to_string))
        .collect()
}

fn check_plain(m: &TopoMap) {
    let svg = render_svg(
        m,
        &RenderOptions {
            title: Some(format!("{} <&> \"test\"", m.name)),
            ..RenderOptions::default()
        },
    );
    let doc = roxmltree::Document::parse(&svg).expect("well-formed XML");
    assert_eq!(count_class(&doc, "place"), m.num_places());
    let ph = m.places().filter(|p| p.placeholder).count();
    assert!(ph > 0);
    assert_eq!(count_class(&doc, "placeholder"), ph);
    assert_eq!(count_class(&doc, "edge"), m.num_edges());
    assert_eq!(count_class(&doc, "legend-swatch"), m.classes.len());
    let t = texts(&doc);
    assert!(
        t.iter().any(|s| s.ends_with("<&> \"test\"")),
        "title escaped and parsed back"
    );
    for name in m.classes.names() {
        assert!(t.contains(name), "legend has {name}");
    }
    assert_eq!(count_class(&doc, "warning"), 0);
    // Each place group carries its id.
    let ids: Vec<u32> = doc
        .descendants()
        .filter(|n| has_class(n, "place"))
        .map(|n| n.attribute("data-id").unwrap().parse().unwrap())
        .collect();
    assert_eq!(ids, m.places().map(|p| p.id).collect::<Vec<_>>());
}

#[test]
fn renders_synthetic_map() {
    let m = generate(&SyntheticParams::new(400, 3)).unwrap();
    check_plain(&m);
    let a = render_svg(&m, &RenderOptions::default());
    assert_eq!(
        a,
        render_svg(&m, &RenderOptions::default()),
        "deterministic"
    );
}

#[test]
fn renders_cold_map() {
    let dir = cold::data_dir(None);
    let m = cold::load_sequence(dir.join("Freiburg/seq1_cloudy1")).expect("load");
    check_plain(&m);
}

/// Pairs of adjacent places greedily, singletons for the rest (a stand-in
/// decomposition; the real one is the decompose module's).
fn toy_decomposition(m: &TopoMap) -> Decomposition {
    let mut used = vec![false; m.num_places()];
    let mut components = Vec::new();
    for (a, b) in m.edge_list() {
        if !used[a] && !used[b] {
            used[a] = true;
            used[b] = true;
            components.push(Component {
                template: 1,
                places: vec![a, b],
            });
        }
    }
    for (i, u) in used.iter().enumerate() {
        if !u {
            components.push(Component {
                template: 0,
                places: vec![i],
            });
        }
    }
    Decomposition { components }
}

#[test]
fn overlays() {
    let m = generate(&SyntheticParams::new(60, 1)).unwrap();
    let k = m.classes.len();
    let dists: Vec<Vec<f64>> = (0..m.num_places())
        .map(|i| (0..k).map(|c| ((i + c) % 3) as f64).collect())
        .collect();
    let dec = toy_decomposition(&m);
    let templates = [Template::singleton(), Template::pair()];
    let highlight = [0usize, 5];
    let opts = RenderOptions {
        distributions: Some(&dists),
        decomposition: Some(&dec),
        templates: Some(&templates),
        highlight: &highlight,
        ..RenderOptions::default()
    };
    check_options(&m, &opts).unwrap();
    let svg = render_svg(&m, &opts);
    let doc = roxmltree::Document::parse(&svg).unwrap();
    assert_eq!(count_class(&doc, "place"), m.num_places());
    assert_eq!(count_class(&doc, "highlight"), 2);
    let pairs = dec
        .components
        .iter()
        .filter(|c| c.places.len() == 2)
        .count();
    assert_eq!(count_class(&doc, "component-edge"), pairs);
    assert_eq!(count_class(&doc, "legend-template"), 2);
    let t = texts(&doc);
    assert!(t.contains(&"pair".to_string()) && t.contains(&"singleton".to_string()));
    // Pies: 2 of 3 residues non-zero per place → slices drawn as paths.
    assert!(doc.descendants().filter(|n| n.has_tag_name("path")).count() >= m.num_places());
}

#[test]
fn mismatched_options_are_reported() {
    let m = generate(&SyntheticParams::new(30, 2)).unwrap();
    let dists = vec![vec![1.0; m.classes.len()]; 3];
    let opts = RenderOptions {
        distributions: Some(&dists),
        ..RenderOptions::default()
    };
    assert_eq!(
        check_options(&m, &opts),
        Err(RenderError::DistributionCount {
            found: 3,
            places: 30
        })
    );
    let svg = render_svg(&m, &opts);
    let doc = roxmltree::Document::parse(&svg).unwrap();
    assert_eq!(
        count_class(&doc, "warning"),
        1,
        "mismatch is visible, not silent"
    );
    assert_eq!(count_class(&doc, "place"), 30);
    let hl = [99usize];
    let opts = RenderOptions {
        highlight: &hl,
        ..RenderOptions::default()
    };
    assert!(matches!(
        check_options(&m, &opts),
        Err(RenderError::PlaceOutOfRange { index: 99, .. })
    ));
}
