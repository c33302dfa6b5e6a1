//! Synthetic maps for tests and benchmarks of decomposition: seeded random
//! connected graphs with a degree cap, and grids (optionally with diagonals).
//! Places carry no class; ids are `10 + 3·index` so ids and indices differ.

use petgraph::graph::{NodeIndex, UnGraph};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::map::{ClassSet, Place, TopoMap};

fn place(i: usize, x: f64, y: f64) -> Place {
    Place {
        id: 10 + 3 * i as u32,
        class: None,
        placeholder: false,
        x,
        y,
    }
}

/// A random connected map with `num_places ≥ 1` places and degrees at most
/// `max_degree ≥ 2`: a random tree (each new place joined to a random earlier
/// place with spare degree), plus up to `extra_edges` random extra edges
/// (attempts that would exceed the degree cap or repeat an edge are skipped).
pub fn random_connected_map(
    num_places: usize,
    max_degree: usize,
    extra_edges: usize,
    seed: u64,
) -> TopoMap {
    let n = num_places.max(1);
    let max_degree = max_degree.max(2);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut g = UnGraph::<Place, ()>::with_capacity(n, n + extra_edges);
    for i in 0..n {
        g.add_node(place(i, (i % 20) as f64, (i / 20) as f64));
    }
    let mut degree = vec![0usize; n];
    for i in 1..n {
        // A tree on i nodes has average degree < 2 ≤ max_degree, so some
        // earlier place has spare degree; rejection sampling finds one fast.
        let j = loop {
            let j = rng.random_range(0..i);
            if degree[j] < max_degree {
                break j;
            }
        };
        g.add_edge(NodeIndex::new(i), NodeIndex::new(j), ());
        degree[i] += 1;
        degree[j] += 1;
    }
    if n >= 2 {
        for _ in 0..extra_edges {
            let a = rng.random_range(0..n);
            let b = rng.random_range(0..n);
            if a == b
                || degree[a] >= max_degree
                || degree[b] >= max_degree
                || g.find_edge(NodeIndex::new(a), NodeIndex::new(b)).is_some()
            {
                continue;
            }
            g.add_edge(NodeIndex::new(a), NodeIndex::new(b), ());
            degree[a] += 1;
            degree[b] += 1;
        }
    }
    TopoMap {
        name: format!("random-{n}-{max_degree}-{extra_edges}-{seed}"),
        classes: ClassSet::paper(),
        graph: g,
    }
}

/// A `width × height` grid map (place index `y·width + x`), 4-neighbour, or
/// 8-neighbour with `diagonals` (degrees up to 8, like COLD maps).
pub fn grid_map(width: usize, height: usize, diagonals: bool) -> TopoMap {
    let mut g = UnGraph::<Place, ()>::with_capacity(width * height, 4 * width * height);
    for y in 0..height {
        for x in 0..width {
            g.add_node(place(y * width + x, x as f64 * 0.8, y as f64 * 0.8));
        }
    }
    let idx = |x: usize, y: usize| NodeIndex::new(y * width + x);
    for y in 0..height {
        for x in 0..width {
            if x + 1 < width {
                g.add_edge(idx(x, y), idx(x + 1, y), ());
            }
            if y + 1 < height {
                g.add_edge(idx(x, y), idx(x, y + 1), ());
            }
            if diagonals && y + 1 < height {
                if x + 1 < width {
                    g.add_edge(idx(x, y), idx(x + 1, y + 1), ());
                }
                if x > 0 {
                    g.add_edge(idx(x, y), idx(x - 1, y + 1), ());
                }
            }
        }
    }
    TopoMap {
        name: format!(
            "grid-{width}x{height}{}",
            if diagonals { "-diag" } else { "" }
        ),
        classes: ClassSet::paper(),
        graph: g,
    }
}
