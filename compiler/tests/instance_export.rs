//! Export of an instance: the JSON has every node, the dot file is well formed.

mod harness;

use graphspn_compiler::instance::{Instance, InstanceParams};
use graphspn_compiler::spn::Spn;
use harness::instance::{random_model, tiny_map};

#[test]
fn json_has_every_node_and_dot_every_edge() {
    let model = random_model(3, false, 2);
    let map = tiny_map(12, 3, 2);
    let inst = Instance::for_map(&model, &map, &InstanceParams::default()).unwrap();
    let names: Vec<String> = model.templates.iter().map(|t| t.name.clone()).collect();

    let json = inst.to_json(&map, &names);
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(v["format"], 1);
    assert_eq!(
        v["spn"]["nodes"].as_array().unwrap().len(),
        inst.spn.nodes.len()
    );
    assert_eq!(v["place_ids"].as_array().unwrap().len(), map.num_places());
    assert_eq!(
        v["decompositions"].as_array().unwrap().len(),
        inst.decompositions.len()
    );
    let spn: Spn = serde_json::from_value(v["spn"].clone()).unwrap();
    assert_eq!(spn, inst.spn);

    let dot = inst.to_dot(&map);
    assert!(dot.starts_with("digraph"));
    assert_eq!(dot.matches('{').count(), dot.matches('}').count());
    let edge_lines = dot.lines().filter(|l| l.contains("->")).count();
    assert_eq!(edge_lines, inst.spn.num_edges());
    let node_lines = dot
        .lines()
        .filter(|l| l.trim_start().starts_with('n') && l.contains("label=") && !l.contains("->"))
        .count();
    assert_eq!(node_lines, inst.spn.nodes.len());
}
