//! Shared fixtures and the brute-force oracle for the codegen tests.

use graphspn_compiler::decompose::{Component, Decomposition};
use graphspn_compiler::learn::Model;
use graphspn_compiler::map::{ClassSet, Place, TopoMap};
use graphspn_compiler::spn::{Node, NodeId, Spn};
use graphspn_compiler::template::Template;
use petgraph::graph::{NodeIndex, UnGraph};
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A map from an edge list; place ids are `100 + index`.
pub fn map(n: usize, classes: usize, edges: &[(usize, usize)]) -> TopoMap {
    let mut g = UnGraph::new_undirected();
    for i in 0..n {
        g.add_node(Place {
            id: 100 + i as u32,
            class: None,
            placeholder: false,
            x: i as f64,
            y: 0.0,
        });
    }
    for &(a, b) in edges {
        g.update_edge(NodeIndex::new(a), NodeIndex::new(b), ());
    }
    let names = (0..classes).map(|c| format!("C{c}")).collect();
    TopoMap {
        name: format!("test-{n}"),
        classes: ClassSet::new(names).unwrap(),
        graph: g,
    }
}

/// A `w × h` grid map.
pub fn grid(w: usize, h: usize, classes: usize) -> TopoMap {
    let mut edges = vec![];
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            if x + 1 < w {
                edges.push((i, i + 1));
            }
            if y + 1 < h {
                edges.push((i, i + w));
            }
        }
    }
    map(w * h, classes, &edges)
}

/// Crude random decomposition into the given templates (largest first; each template
/// is a pivot, node 0, joined to all its other nodes — true for Star/Three/Pair/Singleton).
pub fn decompose(map: &TopoMap, templates: &[Template], seed: u64) -> Decomposition {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let n = map.num_places();
    let mut used = vec![false; n];
    let mut order: Vec<usize> = (0..n).collect();
    order.shuffle(&mut rng);
    let mut comps = vec![];
    for (t, tpl) in templates.iter().enumerate() {
        for &p in &order {
            if used[p] {
                continue;
            }
            let mut nb: Vec<usize> = map.neighbors(p).into_iter().filter(|&q| !used[q]).collect();
            if nb.len() + 1 < tpl.num_nodes {
                continue;
            }
            nb.shuffle(&mut rng);
            let mut places = vec![p];
            places.extend(&nb[..tpl.num_nodes - 1]);
            for &q in &places {
                used[q] = true;
            }
            comps.push(Component {
                template: t,
                places,
            });
        }
    }
    Decomposition { components: comps }
}

/// A random valid SPN over `n` variables with `c` classes each.
///
/// `zeros`: some weights are exactly zero; `scale`: weights are not normalised.
pub fn random_spn(rng: &mut ChaCha8Rng, n: usize, c: usize, zeros: bool, scale: bool) -> Spn {
    let mut nodes = vec![];
    for v in 0..n {
        for k in 0..c {
            nodes.push(Node::Leaf {
                var: v as u32,
                class: k as u32,
            });
        }
    }
    let vars: Vec<u32> = (0..n as u32).collect();
    let root = build(rng, &vars, c, zeros, scale, &mut nodes);
    Spn {
        classes: vec![c as u32; n],
        nodes,
        root,
    }
}

fn weights(rng: &mut ChaCha8Rng, k: usize, zeros: bool, scale: bool) -> Vec<f64> {
    let mut w: Vec<f64> = (0..k).map(|_| rng.random_range(0.05..1.0)).collect();
    if zeros {
        for x in w.iter_mut().skip(1) {
            if rng.random_bool(0.3) {
                *x = 0.0;
            }
        }
    }
    let s: f64 = w.iter().sum();
    let f = if scale {
        rng.random_range(0.3..3.0)
    } else {
        1.0
    };
    w.iter().map(|x| x / s * f).collect()
}

fn build(
    rng: &mut ChaCha8Rng,
    scope: &[u32],
    c: usize,
    zeros: bool,
    scale: bool,
    nodes: &mut Vec<Node>,
) -> NodeId {
    if scope.len() == 1 {
        let v = scope[0] as usize;
        let children: Vec<NodeId> = (0..c).map(|k| (v * c + k) as NodeId).collect();
        let w = weights(rng, c, zeros, scale);
        nodes.push(Node::Sum {
            children,
            weights: w,
        });
        return (nodes.len() - 1) as NodeId;
    }
    let k = rng.random_range(1..=3);
    let mut prods = vec![];
    for _ in 0..k {
        let mut s = scope.to_vec();
        s.shuffle(rng);
        let parts = rng.random_range(2..=s.len().min(3));
        let mut cuts: Vec<usize> = (1..s.len()).collect();
        cuts.shuffle(rng);
        let mut cuts: Vec<usize> = cuts[..parts - 1].to_vec();
        cuts.sort();
        let mut children = vec![];
        let mut start = 0;
        for &cut in cuts.iter().chain(std::iter::once(&s.len())) {
            children.push(build(rng, &s[start..cut], c, zeros, scale, nodes));
            start = cut;
        }
        nodes.push(Node::Product { children });
        prods.push((nodes.len() - 1) as NodeId);
    }
    let w = weights(rng, prods.len(), zeros, scale);
    nodes.push(Node::Sum {
        children: prods,
        weights: w,
    });
    (nodes.len() - 1) as NodeId
}

/// A model over the given templates with the given SPNs.
pub fn model(classes: usize, templates: Vec<Template>, spns: Vec<Spn>) -> Model {
    Model {
        format: 1,
        family: Default::default(),
        classes: ClassSet::new((0..classes).map(|c| format!("C{c}")).collect()).unwrap(),
        templates,
        spns,
        settings: serde_json::Value::Null,
        trained_on: vec![],
    }
}

/// Evaluates an SPN bottom-up over nodes `0..=id` (independent of the generator's code):
/// leaves take `x[var][class]`; `max` turns sums into max-products.
pub fn eval(spn: &Spn, id: NodeId, x: &[Vec<f64>], max: bool) -> f64 {
    let mut v = Vec::with_capacity(id as usize + 1);
    for n in &spn.nodes[..=id as usize] {
        let val = match n {
            Node::Leaf { var, class } => x[*var as usize][*class as usize],
            Node::Product { children } => children.iter().map(|&c| v[c as usize]).product(),
            Node::Sum { children, weights } => {
                let t = children
                    .iter()
                    .zip(weights)
                    .map(|(&c, w)| w * v[c as usize]);
                if max { t.fold(0.0, f64::max) } else { t.sum() }
            }
        };
        v.push(val);
    }
    v[id as usize]
}

/// Brute-force answers for one evidence array.
#[derive(Debug)]
pub struct Oracle {
    /// `ln S(α)`.
    pub ll: f64,
    /// Marginals.
    pub marg: Vec<Vec<f64>>,
    /// Max-product log value of the instance SPN.
    pub mpe: f64,
    /// `ln S` with α masked by `labels`.
    pub lll: f64,
}

fn comp_rows(x: &[Vec<f64>], places: &[usize]) -> Vec<Vec<f64>> {
    places.iter().map(|&p| x[p].clone()).collect()
}

/// Max-product value of the instance for evidence `x` (not logged).
pub fn max_product(m: &Model, decs: &[Decomposition], x: &[Vec<f64>]) -> f64 {
    let d = decs.len() as f64;
    decs.iter()
        .map(|dec| {
            dec.components
                .iter()
                .map(|k| {
                    let spn = &m.spns[k.template];
                    eval(spn, spn.root, &comp_rows(x, &k.places), true)
                })
                .product::<f64>()
                / d
        })
        .fold(0.0, f64::max)
}

/// Enumerates every labelling `y` of the map: `S = Σ_y Π_p α_p[y_p] P(y)`.
pub fn oracle(m: &Model, decs: &[Decomposition], e: &[Vec<f64>], labels: &[u16]) -> Oracle {
    let n = e.len();
    let c = e[0].len();
    let total = c.pow(n as u32);
    let mut s = 0.0;
    let mut sl = 0.0;
    let mut marg = vec![vec![0.0; c]; n];
    let mut y = vec![0usize; n];
    for _ in 0..total {
        let onehot: Vec<Vec<f64>> = y
            .iter()
            .map(|&k| (0..c).map(|j| if j == k { 1.0 } else { 0.0 }).collect())
            .collect();
        let py: f64 = decs
            .iter()
            .map(|dec| {
                dec.components
                    .iter()
                    .map(|k| {
                        let spn = &m.spns[k.template];
                        eval(spn, spn.root, &comp_rows(&onehot, &k.places), false)
                    })
                    .product::<f64>()
            })
            .sum::<f64>()
            / decs.len() as f64;
        let a: f64 = y.iter().enumerate().map(|(p, &k)| e[p][k]).product();
        let term = a * py;
        s += term;
        if y.iter()
            .zip(labels)
            .all(|(&k, &l)| l == u16::MAX || k == l as usize)
        {
            sl += term;
        }
        for (p, &k) in y.iter().enumerate() {
            marg[p][k] += term;
        }
        for digit in y.iter_mut() {
            *digit += 1;
            if *digit < c {
                break;
            }
            *digit = 0;
        }
    }
    for row in &mut marg {
        for v in row.iter_mut() {
            *v /= s;
        }
    }
    Oracle {
        ll: s.ln(),
        marg,
        mpe: max_product(m, decs, e).ln(),
        lll: sl.ln(),
    }
}

/// The four-place fixture: a path 0–1–2–3, two classes, Pair and Singleton templates
/// with handwritten SPNs, two decompositions.
pub fn tiny() -> (Model, TopoMap, Vec<Decomposition>) {
    let mut nodes: Vec<Node> = vec![];
    for v in 0..2 {
        for k in 0..2 {
            nodes.push(Node::Leaf { var: v, class: k });
        }
    }
    // products x0[a]·x1[b] at ids 4..8, root sum at 8
    for a in 0..2u32 {
        for b in 0..2u32 {
            nodes.push(Node::Product {
                children: vec![a, 2 + b],
            });
        }
    }
    nodes.push(Node::Sum {
        children: vec![4, 5, 6, 7],
        weights: vec![0.4, 0.1, 0.2, 0.3],
    });
    let pair = Spn {
        classes: vec![2, 2],
        nodes,
        root: 8,
    };
    let single = super::learn::indicator_sum(vec![0.5, 0.5]);
    let m = model(
        2,
        vec![Template::pair(), Template::singleton()],
        vec![pair, single],
    );
    let mp = map(4, 2, &[(0, 1), (1, 2), (2, 3)]);
    let decs = vec![
        Decomposition {
            components: vec![
                Component {
                    template: 0,
                    places: vec![0, 1],
                },
                Component {
                    template: 0,
                    places: vec![2, 3],
                },
            ],
        },
        Decomposition {
            components: vec![
                Component {
                    template: 1,
                    places: vec![0],
                },
                Component {
                    template: 0,
                    places: vec![1, 2],
                },
                Component {
                    template: 1,
                    places: vec![3],
                },
            ],
        },
    ];
    (m, mp, decs)
}

/// Replaces every sum's weights by random normalised ones (all `> 0`), keeping the
/// structure: dense structures come with near-uniform weights, which make MPE ties likely.
pub fn randomise_weights(spn: &mut Spn, rng: &mut ChaCha8Rng) {
    for n in spn.nodes.iter_mut() {
        if let Node::Sum { weights, .. } = n {
            let w: Vec<f64> = (0..weights.len())
                .map(|_| rng.random_range(0.05..1.0))
                .collect();
            let s: f64 = w.iter().sum();
            *weights = w.iter().map(|x| x / s).collect();
        }
    }
}

/// A model with the real structure of `learn` (symmetric dense Star/Three/Pair with the
/// authors' parameters, or plain dense ones with `decompositions` random splits per
/// region), random weights, uniform Singleton, `classes` classes.
pub fn dense_model(classes: usize, symmetric: bool, decompositions: usize, seed: u64) -> Model {
    let params = graphspn_compiler::learn::DenseParams {
        decompositions,
        ..Default::default()
    };
    dense_model_with(classes, symmetric, &params, seed)
}

/// [`dense_model`] with the given structure parameters.
pub fn dense_model_with(
    classes: usize,
    symmetric: bool,
    params: &graphspn_compiler::learn::DenseParams,
    seed: u64,
) -> Model {
    use graphspn_compiler::learn::{dense_structure, symmetric_dense_structure, uniform_spn};
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let templates = Template::paper_set();
    let spns = templates
        .iter()
        .map(|t| {
            if t.num_nodes == 1 {
                return uniform_spn(1, classes as u32).unwrap();
            }
            let mut spn = if symmetric {
                symmetric_dense_structure(
                    t.num_nodes,
                    classes as u32,
                    params,
                    &t.automorphisms(),
                    seed,
                )
            } else {
                dense_structure(t.num_nodes, classes as u32, params, seed)
            }
            .unwrap();
            randomise_weights(&mut spn, &mut rng);
            spn
        })
        .collect();
    model(classes, templates, spns)
}
