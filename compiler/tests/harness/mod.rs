//! Helpers shared by the compiler crate's tests and benches: enumerations used by
//! brute-force oracles (here), and per area [`codegen`] (fixtures and the brute-force
//! oracle of the generated code), [`instance`] (small random models, maps, evidence)
//! and [`learn`] (automorphism groups, a brute-force SPN evaluator, a synthetic
//! sampler); [`temp_crate`] sets up the temporary crates of generated code. Test files include it with `mod harness;`, the benches with `#[path]`.
#![allow(dead_code)]

pub mod codegen;
pub mod instance;
pub mod learn;
pub mod temp_crate;
pub mod treemix;

/// Every full assignment of variables with `classes[v]` classes each, the first
/// variable slowest.
pub fn all_assignments(classes: &[u32]) -> Vec<Vec<u32>> {
    let mut out = vec![vec![]];
    for &k in classes {
        out = out
            .into_iter()
            .flat_map(|p| {
                (0..k).map(move |c| {
                    let mut q = p.clone();
                    q.push(c);
                    q
                })
            })
            .collect();
    }
    out
}

/// All permutations of `items`, in lexicographic order of positions.
pub fn permutations(items: &[usize]) -> Vec<Vec<usize>> {
    if items.len() <= 1 {
        return vec![items.to_vec()];
    }
    let mut out = Vec::new();
    for i in 0..items.len() {
        let mut rest = items.to_vec();
        let x = rest.remove(i);
        for mut p in permutations(&rest) {
            p.insert(0, x);
            out.push(p);
        }
    }
    out
}
