//! The greedy random decomposition (Alg. 2) and the best-of-N scheme.

use crate::par::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::{Component, DecomposeError, Decomposition};
use crate::map::TopoMap;
use crate::template::{Adjacency, Matcher, Template};

/// How [`decompose_best`] draws and ranks its candidate decompositions.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DecompositionStrategy {
    /// The authors' scheme (Alg. 2): random matches; candidates are partitions by
    /// the largest template ranked by its coverage, the best completed with the
    /// smaller templates.
    #[default]
    Paper,
    /// Covering: a star-shaped template takes the free neighbours of its pivot
    /// that have the fewest other free neighbours first (so a frontier place
    /// joins its only neighbour's component rather than becoming a singleton);
    /// candidates are complete decompositions ranked by fewest singletons, then
    /// by coverage of the largest template.
    Cover,
}

impl DecompositionStrategy {
    /// Both strategies, in a fixed order.
    pub const ALL: [DecompositionStrategy; 2] =
        [DecompositionStrategy::Paper, DecompositionStrategy::Cover];

    /// Short name (`paper`, `cover`), as in files and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            DecompositionStrategy::Paper => "paper",
            DecompositionStrategy::Cover => "cover",
        }
    }

    /// The strategy called `name` (see [`DecompositionStrategy::name`]).
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|s| s.name() == name)
    }
}

/// Largest number of decompositions an instance mixes (every command and settings
/// file is held to it).
pub const MAX_DECOMPOSITIONS: usize = 1000;

/// Largest number of candidate decompositions drawn.
pub const MAX_CANDIDATES: usize = 3 * MAX_DECOMPOSITIONS;

/// Settings of [`decompose_best`]. Defaults are the authors': 15 candidates,
/// best 5 kept, [`DecompositionStrategy::Paper`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DecompositionParams {
    /// Number of decompositions returned (K).
    pub count: usize,
    /// Number of random candidates scored (N ≥ K).
    pub candidates: usize,
    /// Seed of every random choice.
    pub seed: u64,
    /// How candidates are drawn and ranked.
    pub strategy: DecompositionStrategy,
}

impl Default for DecompositionParams {
    fn default() -> Self {
        DecompositionParams {
            count: 5,
            candidates: 15,
            seed: 0,
            strategy: DecompositionStrategy::Paper,
        }
    }
}

/// Templates checked and ready to match on one map.
struct Prepared {
    adj: Adjacency,
    /// Template indices, largest first (nodes, then edges, then list order).
    order: Vec<usize>,
    /// Matchers, indexed by template index.
    matchers: Vec<Matcher>,
}

fn prepare(map: &TopoMap, templates: &[Template]) -> Result<Prepared, DecomposeError> {
    if templates.is_empty() {
        return Err(DecomposeError::NoTemplates);
    }
    let mut matchers = Vec::with_capacity(templates.len());
    for (i, t) in templates.iter().enumerate() {
        matchers.push(Matcher::new(t)?);
        if templates[..i].iter().any(|u| u.name == t.name) {
            return Err(DecomposeError::DuplicateTemplateName {
                name: t.name.clone(),
            });
        }
    }
    if !templates.iter().any(|t| t.num_nodes == 1) {
        return Err(DecomposeError::NoSingleton);
    }
    let mut order: Vec<usize> = (0..templates.len()).collect();
    order.sort_by_key(|&i| {
        (
            std::cmp::Reverse(templates[i].num_nodes),
            std::cmp::Reverse(templates[i].edges.len()),
            i,
        )
    });
    Ok(Prepared {
        adj: Adjacency::new(map),
        order,
        matchers,
    })
}

/// One greedy stage of Alg. 2 for template `t`: covers unused places with
/// random matches of `t` until no match is left among them.
///
/// The paper repeats "pick a random place where the template matches among the
/// unused places, take a random match there". We instead visit the unused places once,
/// in a uniformly random order, and take a random match at each place where one
/// exists when it is visited. This has the same distribution, and one pass
/// suffices:
/// - matchability only decreases: places only ever become used, so a place
///   where no match exists at its visit never gets one later — skipping it for
///   good is exactly what the paper's loop would do, and when the pass ends no
///   place admits a match (maximality);
/// - given everything seen so far (which places came first, which were
///   matchable, the matches taken), the order of the places not visited yet is
///   still uniformly random, and every currently matchable place is among them
///   (visited ones are used or unmatchable). So the next place where a match is
///   taken is the first matchable one in a uniform random order, i.e. uniform
///   among the currently matchable places — the paper's choice.
///
/// With `cover`, matches are taken with [`Matcher::find_covering_at`].
fn greedy_stage<R: Rng + ?Sized>(
    prep: &Prepared,
    t: usize,
    used: &mut [bool],
    rng: &mut R,
    components: &mut Vec<Component>,
    cover: bool,
) {
    let matcher = &prep.matchers[t];
    // Used places never admit a match, so only the unused ones are visited.
    let mut perm: Vec<usize> = (0..used.len()).filter(|&p| !used[p]).collect();
    let n = perm.len();
    for i in 0..n.saturating_sub(1) {
        let j = rng.random_range(i..n);
        perm.swap(i, j);
    }
    let mut buf = Vec::with_capacity(matcher.num_nodes());
    for root in perm {
        let found = !used[root]
            && if cover {
                matcher.find_covering_at(&prep.adj, root, used, rng, &mut buf)
            } else {
                matcher.find_at(&prep.adj, root, used, rng, &mut buf)
            };
        if found {
            for &p in &buf {
                used[p] = true;
            }
            components.push(Component {
                template: t,
                places: buf.clone(),
            });
        }
    }
}

/// One random decomposition of `map` (the paper's Alg. 2): templates in
/// decreasing size (nodes, then edges; ties in list order), each matched
/// greedily at random places among the still-unused ones until none matches.
/// `Component::template` indexes `templates`. Needs a 1-node template so the
/// result is a partition.
pub fn decompose<R: Rng + ?Sized>(
    map: &TopoMap,
    templates: &[Template],
    rng: &mut R,
) -> Result<Decomposition, DecomposeError> {
    let prep = prepare(map, templates)?;
    let mut used = vec![false; map.num_places()];
    let mut components = Vec::new();
    for &t in &prep.order {
        greedy_stage(&prep, t, &mut used, rng, &mut components, false);
    }
    Ok(Decomposition { components })
}

/// The best `params.count` of `params.candidates` random decompositions, best
/// first. With [`DecompositionStrategy::Paper`] (the authors' scheme, as in their
/// published code) each candidate is a random greedy partition by the largest
/// template, scored by its coverage (number of places inside it); the best are
/// completed with the smaller templates. With [`DecompositionStrategy::Cover`]
/// each candidate is a complete covering decomposition, ranked by fewest
/// singleton components, then by the largest template's coverage. Ties: lower
/// candidate number first.
///
/// Candidate `c` draws from `ChaCha8Rng::seed_from_u64(params.seed)` on stream
/// `c`, so results do not depend on thread scheduling.
pub fn decompose_best(
    map: &TopoMap,
    templates: &[Template],
    params: &DecompositionParams,
) -> Result<Vec<Decomposition>, DecomposeError> {
    if params.count == 0 {
        return Err(DecomposeError::BadParams("count must be at least 1".into()));
    }
    if params.candidates < params.count {
        return Err(DecomposeError::BadParams(format!(
            "candidates ({}) must be at least count ({})",
            params.candidates, params.count
        )));
    }
    let prep = prepare(map, templates)?;
    let n = map.num_places();
    let first = prep.order[0];
    let cover = params.strategy == DecompositionStrategy::Cover;
    // Candidates: the stages run now (all of them when covering, else the first).
    let stages = if cover { prep.order.len() } else { 1 };
    let mut cands: Vec<(usize, ChaCha8Rng, Vec<bool>, Vec<Component>)> = (0..params.candidates)
        .into_par_iter()
        .map(|c| {
            let mut rng = ChaCha8Rng::seed_from_u64(params.seed);
            rng.set_stream(c as u64);
            let mut used = vec![false; n];
            let mut comps = Vec::new();
            for &t in &prep.order[..stages] {
                greedy_stage(&prep, t, &mut used, &mut rng, &mut comps, cover);
            }
            (c, rng, used, comps)
        })
        .collect();
    // Coverage = number of places in components of the largest template.
    let coverage = |comps: &[Component]| {
        comps
            .iter()
            .filter(|c| c.template == first)
            .map(|c| c.places.len())
            .sum::<usize>()
    };
    let singletons = |comps: &[Component]| comps.iter().filter(|c| c.places.len() == 1).count();
    cands.sort_by_key(|(c, _, _, comps)| {
        (
            if cover { singletons(comps) } else { 0 },
            std::cmp::Reverse(coverage(comps)),
            *c,
        )
    });
    cands.truncate(params.count);
    let out = cands
        .into_par_iter()
        .map(|(_, mut rng, mut used, mut comps)| {
            for &t in &prep.order[stages..] {
                greedy_stage(&prep, t, &mut used, &mut rng, &mut comps, cover);
            }
            Decomposition { components: comps }
        })
        .collect();
    Ok(out)
}

/// Share of places per template (indexed like `templates`), pooled over the
/// [`decompose_best`] decompositions of every map in `maps` (each map uses
/// `params` as given). Empty input gives all zeros.
pub fn template_shares(
    maps: &[TopoMap],
    templates: &[Template],
    params: &DecompositionParams,
) -> Result<Vec<f64>, DecomposeError> {
    let mut counts = vec![0usize; templates.len()];
    let mut total = 0usize;
    for map in maps {
        for d in decompose_best(map, templates, params)? {
            for (c, k) in counts
                .iter_mut()
                .zip(d.template_node_counts(templates.len()))
            {
                *c += k;
            }
            total += map.num_places();
        }
    }
    Ok(counts
        .iter()
        .map(|&c| {
            if total == 0 {
                0.0
            } else {
                c as f64 / total as f64
            }
        })
        .collect())
}
