//! Finding matches of a template in a map, rooted at a pivot place.
//!
//! A match sends template node 0 (the pivot) to a given *root* place and every
//! other template node to a distinct place not yet used, such that every
//! template edge is a map edge (subgraph monomorphism; extra edges between the
//! matched places are allowed).
//!
//! petgraph's VF2 (`subgraph_isomorphisms_iter`) only finds *node-induced*
//! subgraphs (its docs say so: "'subgraph' always means a 'node-induced
//! subgraph'"), which would wrongly reject e.g. a Three whose leaves are
//! adjacent; and it is not rooted. So matching is done here:
//!
//! - star-shaped templates (node 0 joined to every other node and no other
//!   edges: Singleton, Pair, Three, Star) use a dedicated matcher that picks
//!   `k` random unused neighbours of the root;
//! - any other connected template uses a small randomised backtracking search
//!   over the template nodes in breadth-first order from node 0, each node
//!   drawn among the unused neighbours of its already-placed BFS parent.

use rand::{Rng, RngCore};

use super::{Template, TemplateError};
use crate::map::TopoMap;

/// Compressed, sorted adjacency lists of a map (fast neighbour access and
/// `O(log d)` edge tests for matching).
#[derive(Clone, Debug)]
pub struct Adjacency {
    offsets: Vec<usize>,
    targets: Vec<usize>,
}

impl Adjacency {
    /// Builds the adjacency of `map` (neighbours ascending, duplicates and
    /// self-loops dropped).
    pub fn new(map: &TopoMap) -> Self {
        let n = map.num_places();
        let mut lists: Vec<Vec<usize>> = vec![Vec::new(); n];
        for e in map.graph.edge_indices() {
            if let Some((a, b)) = map.graph.edge_endpoints(e) {
                let (a, b) = (a.index(), b.index());
                if a != b {
                    lists[a].push(b);
                    lists[b].push(a);
                }
            }
        }
        let mut offsets = Vec::with_capacity(n + 1);
        let mut targets = Vec::with_capacity(2 * map.num_edges());
        offsets.push(0);
        for mut l in lists {
            l.sort_unstable();
            l.dedup();
            targets.extend_from_slice(&l);
            offsets.push(targets.len());
        }
        Adjacency { offsets, targets }
    }

    /// Number of places.
    pub fn num_places(&self) -> usize {
        self.offsets.len() - 1
    }

    /// Neighbours of place `i`, ascending.
    pub fn neighbors(&self, i: usize) -> &[usize] {
        &self.targets[self.offsets[i]..self.offsets[i + 1]]
    }

    /// Whether places `a` and `b` are adjacent.
    pub fn has_edge(&self, a: usize, b: usize) -> bool {
        self.neighbors(a).binary_search(&b).is_ok()
    }
}

#[derive(Clone, Debug)]
enum Kind {
    /// Node 0 joined to nodes `1..=leaves`, nothing else.
    Star { leaves: usize },
    /// Backtracking in BFS order.
    General {
        /// Template nodes in BFS order from node 0 (`order[0] == 0`).
        order: Vec<usize>,
        /// For `order[k]`, `k ≥ 1`: a template neighbour placed earlier.
        parent: Vec<usize>,
        /// For `order[k]`: the other template neighbours placed earlier, whose
        /// images must be adjacent to the image of `order[k]`.
        checks: Vec<Vec<usize>>,
    },
}

/// A prepared matcher for one template.
#[derive(Clone, Debug)]
pub struct Matcher {
    num_nodes: usize,
    kind: Kind,
}

impl Matcher {
    /// A matcher for `template` (validated first): the dedicated star matcher
    /// when the template is star-shaped around node 0, else backtracking.
    pub fn new(template: &Template) -> Result<Self, TemplateError> {
        template.validate()?;
        let n = template.num_nodes;
        let star_shaped =
            template.edges.len() == n - 1 && template.edges.iter().all(|&(a, _)| a == 0);
        if star_shaped {
            Ok(Matcher {
                num_nodes: n,
                kind: Kind::Star { leaves: n - 1 },
            })
        } else {
            Self::general(template)
        }
    }

    /// A backtracking matcher for `template` (validated first), even when it is
    /// star-shaped; used to cross-check the dedicated matcher.
    pub fn general(template: &Template) -> Result<Self, TemplateError> {
        template.validate()?;
        let n = template.num_nodes;
        let adj = template.adjacency_matrix();
        let mut order = vec![0];
        let mut parent = vec![usize::MAX];
        let mut placed = vec![false; n];
        placed[0] = true;
        let mut head = 0;
        while head < order.len() {
            let u = order[head];
            head += 1;
            for v in 0..n {
                if adj[u][v] && !placed[v] {
                    placed[v] = true;
                    order.push(v);
                    parent.push(u);
                }
            }
        }
        // `validate` guarantees connectivity, hence `order` covers all nodes.
        let mut checks = Vec::with_capacity(n);
        for (k, &t) in order.iter().enumerate() {
            let earlier = &order[..k];
            checks.push(
                earlier
                    .iter()
                    .copied()
                    .filter(|&e| adj[t][e] && e != parent[k])
                    .collect(),
            );
        }
        Ok(Matcher {
            num_nodes: n,
            kind: Kind::General {
                order,
                parent,
                checks,
            },
        })
    }

    /// Whether this matcher uses the dedicated star-shaped fast path.
    pub fn is_dedicated(&self) -> bool {
        matches!(self.kind, Kind::Star { .. })
    }

    /// Number of template nodes.
    pub fn num_nodes(&self) -> usize {
        self.num_nodes
    }

    /// Looks for a random match with template node 0 at `root`, among places
    /// with `used[p] == false`. On success writes the places in template node
    /// order into `out` and returns `true`; on failure returns `false` (`out`
    /// is then unspecified). `used` must have one entry per place.
    pub fn find_at<R: Rng + ?Sized>(
        &self,
        adj: &Adjacency,
        root: usize,
        used: &[bool],
        rng: &mut R,
        out: &mut Vec<usize>,
    ) -> bool {
        let mut dyn_rng = RngAdapter(rng);
        self.search(adj, root, used, Some(&mut dyn_rng), out)
    }

    /// Like [`Matcher::find_at`], but a star-shaped template takes the unused
    /// neighbours of `root` that have the fewest *other* unused neighbours first
    /// (ties in random order): a place whose only free neighbour is `root` (a
    /// placeholder at the frontier, say) joins this component instead of being
    /// left to become a singleton. Other templates match as in `find_at`.
    pub fn find_covering_at<R: Rng + ?Sized>(
        &self,
        adj: &Adjacency,
        root: usize,
        used: &[bool],
        rng: &mut R,
        out: &mut Vec<usize>,
    ) -> bool {
        let mut dyn_rng = RngAdapter(rng);
        self.search_with(adj, root, used, Some(&mut dyn_rng), true, out)
    }

    /// Whether any match with template node 0 at `root` exists among places
    /// with `used[p] == false` (deterministic, no randomness).
    pub fn exists_at(&self, adj: &Adjacency, root: usize, used: &[bool]) -> bool {
        let mut out = Vec::with_capacity(self.num_nodes);
        self.search(adj, root, used, None, &mut out)
    }

    fn search(
        &self,
        adj: &Adjacency,
        root: usize,
        used: &[bool],
        rng: Option<&mut dyn RngCore>,
        out: &mut Vec<usize>,
    ) -> bool {
        self.search_with(adj, root, used, rng, false, out)
    }

    /// [`Matcher::search`]; with `cover`, a star's leaves are the free neighbours
    /// with the fewest other free neighbours (ties in random order).
    fn search_with(
        &self,
        adj: &Adjacency,
        root: usize,
        used: &[bool],
        mut rng: Option<&mut dyn RngCore>,
        cover: bool,
        out: &mut Vec<usize>,
    ) -> bool {
        out.clear();
        if used[root] {
            return false;
        }
        match &self.kind {
            Kind::Star { leaves } => {
                let leaves = *leaves;
                out.push(root);
                out.extend(adj.neighbors(root).iter().copied().filter(|&v| !used[v]));
                if out.len() < leaves + 1 {
                    return false;
                }
                let len = out.len();
                if let Some(rng) = rng.as_deref_mut() {
                    // Partial Fisher–Yates on out[1..]: a uniformly random
                    // ordered choice of `leaves` distinct neighbours (all of them
                    // shuffled when covering, so the sort below keeps ties random).
                    let end = if cover { len - 1 } else { leaves + 1 };
                    for i in 1..end {
                        let j = rng.random_range(i..len);
                        out.swap(i, j);
                    }
                }
                if cover {
                    // Stable: equal free degrees keep their random order.
                    out[1..].sort_by_cached_key(|&v| {
                        adj.neighbors(v)
                            .iter()
                            .filter(|&&w| w != root && !used[w])
                            .count()
                    });
                }
                out.truncate(leaves + 1);
                true
            }
            Kind::General {
                order,
                parent,
                checks,
            } => {
                let n = self.num_nodes;
                out.resize(n, usize::MAX);
                out[0] = root;
                let ctx = General {
                    adj,
                    used,
                    order,
                    parent,
                    checks,
                };
                ctx.extend(1, out, &mut rng)
            }
        }
    }
}

struct General<'a> {
    adj: &'a Adjacency,
    used: &'a [bool],
    order: &'a [usize],
    parent: &'a [usize],
    checks: &'a [Vec<usize>],
}

impl General<'_> {
    /// Places template nodes `order[k..]` given `img` for `order[..k]`.
    fn extend(&self, k: usize, img: &mut [usize], rng: &mut Option<&mut dyn RngCore>) -> bool {
        if k == self.order.len() {
            return true;
        }
        let t = self.order[k];
        let p = img[self.parent[k]];
        let placed = &self.order[..k];
        let mut cands: Vec<usize> = self
            .adj
            .neighbors(p)
            .iter()
            .copied()
            .filter(|&v| {
                !self.used[v]
                    && !placed.iter().any(|&q| img[q] == v)
                    && self.checks[k].iter().all(|&c| self.adj.has_edge(v, img[c]))
            })
            .collect();
        if let Some(rng) = rng.as_deref_mut() {
            let len = cands.len();
            for i in 0..len.saturating_sub(1) {
                let j = rng.random_range(i..len);
                cands.swap(i, j);
            }
        }
        for v in cands {
            img[t] = v;
            if self.extend(k + 1, img, rng) {
                return true;
            }
        }
        img[t] = usize::MAX;
        false
    }
}

/// Lets a generic `Rng` be used through `dyn RngCore`.
struct RngAdapter<'a, R: ?Sized>(&'a mut R);

impl<R: RngCore + ?Sized> RngCore for RngAdapter<'_, R> {
    fn next_u32(&mut self) -> u32 {
        self.0.next_u32()
    }
    fn next_u64(&mut self) -> u64 {
        self.0.next_u64()
    }
    fn fill_bytes(&mut self, dst: &mut [u8]) {
        self.0.fill_bytes(dst)
    }
}
