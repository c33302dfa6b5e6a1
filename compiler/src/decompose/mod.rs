//! Decompositions of a map into template-shaped components (the paper's Alg. 2).

use serde::{Deserialize, Serialize};

/// One component of a decomposition: a copy of a template placed on the map.
#[derive(Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct Component {
    /// Index of the template in the template list the decomposition was made with.
    pub template: usize,
    /// Place indices (map place order), in the template's canonical node order.
    pub places: Vec<usize>,
}

/// A partition of all places of a map into template-shaped components.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Decomposition {
    /// The components; every place appears in exactly one.
    pub components: Vec<Component>,
}
