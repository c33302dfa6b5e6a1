//! How the components of a mixture (decompositions, trees) are combined into marginals.

/// How a mixture's components' marginals are combined: the decompositions of an
/// instance GraphSPN (`instance::ComponentInstance::marginals_mixed`) or the trees
/// of a tree mixture (`treemix`).
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "snake_case")]
pub enum Mixing {
    /// Weight `P(d | evidence)` per mixture component `d`: the exact marginals of
    /// the mixture (the instance GraphSPN of D decompositions, or the tree mixture).
    #[default]
    Posterior,
    /// Weight `1/D`: the mean of the D components' exact marginals. For GraphSPN, with a
    /// posterior weight the best-fitting decomposition usually dominates (one
    /// decomposition carries most of the weight on COLD maps), so each place sees
    /// only its component in that decomposition; the average lets every place
    /// see all D of its neighbourhoods. Not the posterior of one model.
    Average,
}

impl Mixing {
    /// Both, in a fixed order.
    pub const ALL: [Mixing; 2] = [Mixing::Posterior, Mixing::Average];

    /// Short name (`posterior`, `average`).
    pub fn name(self) -> &'static str {
        match self {
            Mixing::Posterior => "posterior",
            Mixing::Average => "average",
        }
    }

    /// The mixing called `name` (see [`Mixing::name`]).
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|m| m.name() == name)
    }
}
