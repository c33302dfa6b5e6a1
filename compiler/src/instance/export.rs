//! Export of an instance GraphSPN for other tools: JSON (every node) and Graphviz dot.

use std::fmt::Write as _;

use serde::Serialize;

use super::Instance;
use crate::map::TopoMap;
use crate::spn::Node;

/// Version of the instance JSON format.
pub const INSTANCE_FORMAT: u32 = 1;

#[derive(Serialize)]
struct InstanceJson<'a> {
    format: u32,
    map: &'a str,
    classes: &'a [String],
    /// Place id of each SPN variable.
    place_ids: Vec<u32>,
    decompositions: Vec<Vec<ComponentJson<'a>>>,
    spn: &'a crate::spn::Spn,
}

#[derive(Serialize)]
struct ComponentJson<'a> {
    template: &'a str,
    places: Vec<u32>,
}

impl Instance {
    /// The whole instance as pretty JSON: class names, the place id of each variable,
    /// the decompositions (template names and place ids) and every SPN node.
    pub fn to_json(&self, map: &TopoMap, template_names: &[String]) -> String {
        let doc = InstanceJson {
            format: INSTANCE_FORMAT,
            map: &map.name,
            classes: map.classes.names(),
            place_ids: map.places().map(|p| p.id).collect(),
            decompositions: self
                .decompositions
                .iter()
                .map(|d| {
                    d.components
                        .iter()
                        .map(|c| ComponentJson {
                            template: &template_names[c.template],
                            places: c.places.iter().map(|&p| map.place(p).id).collect(),
                        })
                        .collect()
                })
                .collect(),
            spn: &self.spn,
        };
        let mut s =
            serde_json::to_string_pretty(&doc).expect("instance JSON serialisation cannot fail");
        s.push('\n');
        s
    }

    /// The instance SPN as a Graphviz digraph: sums `+`, products `×`, leaves
    /// `place=class`; sum edges labelled with their weights. Edges point from parent to child.
    pub fn to_dot(&self, map: &TopoMap) -> String {
        let mut s = String::new();
        let _ = writeln!(s, "digraph instance {{");
        let _ = writeln!(
            s,
            "  label=\"instance GraphSPN of {}\";",
            map.name.replace('"', "\\\"")
        );
        let _ = writeln!(s, "  node [fontname=\"Helvetica\"];");
        for (i, node) in self.spn.nodes.iter().enumerate() {
            match node {
                Node::Leaf { var, class } => {
                    let place = map.place(*var as usize).id;
                    let class = map.classes.name(*class as u16);
                    let _ = writeln!(s, "  n{i} [shape=box,label=\"{place}={class}\"];");
                }
                Node::Sum { children, weights } => {
                    let _ = writeln!(s, "  n{i} [shape=circle,label=\"+\"];");
                    for (c, w) in children.iter().zip(weights) {
                        let _ = writeln!(s, "  n{i} -> n{c} [label=\"{w:.4}\"];");
                    }
                }
                Node::Product { children } => {
                    let _ = writeln!(s, "  n{i} [shape=circle,label=\"×\"];");
                    for c in children {
                        let _ = writeln!(s, "  n{i} -> n{c};");
                    }
                }
            }
        }
        let _ = writeln!(s, "}}");
        s
    }
}
