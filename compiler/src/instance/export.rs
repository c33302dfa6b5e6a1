//! Export of an instance GraphSPN for other tools: JSON (every node) and Graphviz dot.

use std::fmt::Write as _;

use serde::Serialize;

use super::Instance;
use crate::map::TopoMap;
use crate::spn::{Node, Spn};
use crate::treemix::SpanningTrees;

/// Version of the instance JSON format.
pub const INSTANCE_FORMAT: u32 = 1;

#[derive(Serialize)]
struct InstanceJson<'a> {
    format: u32,
    map: &'a str,
    classes: &'a [String],
    /// Place id of each SPN variable.
    place_ids: Vec<u32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    decompositions: Option<Vec<Vec<ComponentJson<'a>>>>,
    /// Tree mixtures: each tree's edges as `[parent id, child id]`.
    #[serde(skip_serializing_if = "Option::is_none")]
    trees: Option<Vec<Vec<[u32; 2]>>>,
    spn: &'a crate::spn::Spn,
}

fn pretty(doc: &InstanceJson<'_>) -> String {
    let mut s = serde_json::to_string_pretty(doc).expect("instance JSON serialisation cannot fail");
    s.push('\n');
    s
}

/// The explicit instance SPN of a tree mixture ([`crate::treemix::instance_spn`]) as
/// pretty JSON: like [`Instance::to_json`] with the trees (edges as `[parent id,
/// child id]`) in place of the decompositions.
pub fn tree_instance_json(map: &TopoMap, trees: &SpanningTrees, spn: &Spn) -> String {
    let id = |i: u32| map.place(i as usize).id;
    pretty(&InstanceJson {
        format: INSTANCE_FORMAT,
        map: &map.name,
        classes: map.classes.names(),
        place_ids: map.places().map(|p| p.id).collect(),
        decompositions: None,
        trees: Some(
            trees
                .forests
                .iter()
                .map(|f| f.edges().into_iter().map(|(p, c)| [id(p), id(c)]).collect())
                .collect(),
        ),
        spn,
    })
}

/// `text` inside a Graphviz quoted string: backslashes, quotes and line breaks
/// escaped, so that a name ending in `\` or holding `"` cannot end the string.
fn dot_text(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '\\' => out.push_str("\\\\"),
            '"' => out.push_str("\\\""),
            '\n' => out.push_str("\\n"),
            '\r' => {}
            c => out.push(c),
        }
    }
    out
}

/// An SPN over the places of `map` as a Graphviz digraph: sums `+`, products `×`,
/// leaves `place=class`; sum edges labelled with their weights. Edges point from
/// parent to child; `label` is the graph's title.
pub fn spn_dot(map: &TopoMap, spn: &Spn, label: &str) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "digraph instance {{");
    let _ = writeln!(s, "  label=\"{}\";", dot_text(label));
    let _ = writeln!(s, "  node [fontname=\"Helvetica\"];");
    for (i, node) in spn.nodes.iter().enumerate() {
        match node {
            Node::Leaf { var, class } => {
                let place = map.place(*var as usize).id;
                let class = dot_text(map.classes.name(*class as u16));
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

#[derive(Serialize)]
struct ComponentJson<'a> {
    template: &'a str,
    places: Vec<u32>,
}

impl Instance {
    /// The whole instance as pretty JSON: class names, the place id of each variable,
    /// the decompositions (template names and place ids) and every SPN node.
    pub fn to_json(&self, map: &TopoMap, template_names: &[String]) -> String {
        pretty(&InstanceJson {
            format: INSTANCE_FORMAT,
            map: &map.name,
            classes: map.classes.names(),
            place_ids: map.places().map(|p| p.id).collect(),
            decompositions: Some(
                self.decompositions
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
            ),
            trees: None,
            spn: &self.spn,
        })
    }

    /// The instance SPN as a Graphviz digraph: sums `+`, products `×`, leaves
    /// `place=class`; sum edges labelled with their weights. Edges point from parent to child.
    pub fn to_dot(&self, map: &TopoMap) -> String {
        spn_dot(
            map,
            &self.spn,
            &format!("instance GraphSPN of {}", map.name),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::dot_text;

    /// A name ending in a backslash or holding a quote stays inside its string.
    #[test]
    fn dot_strings_escape_backslashes_quotes_and_line_breaks() {
        assert_eq!(dot_text(r"room\"), r"room\\");
        assert_eq!(dot_text(r#"a"b"#), r#"a\"b"#);
        assert_eq!(dot_text("two\nlines\r"), r"two\nlines");
        assert_eq!(dot_text("Büro 1"), "Büro 1");
    }
}
