//! Loopy BP against brute-force enumeration: exact on trees, bounded error on
//! small loopy graphs, honest convergence reporting.

use graphspn_compiler::mrf::{
    BpOptions, FactorGraph, MrfError, Schedule, exact_inference, loopy_bp,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn random_table(rng: &mut ChaCha8Rng, size: usize, extreme: bool) -> Vec<f64> {
    (0..size)
        .map(|_| {
            if extreme {
                match rng.random_range(0..6) {
                    0 => 0.0,
                    1 => 1e-300,
                    2 => 1e-150 * rng.random_range(0.5..2.0),
                    _ => rng.random_range(0.01..3.0),
                }
            } else {
                rng.random_range(0.05..3.0)
            }
        })
        .collect()
}

/// A random tree-shaped factor graph: each new factor joins one existing
/// variable to one or two new ones; unary factors on random variables.
fn random_tree(seed: u64, extreme: bool) -> FactorGraph {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let n = rng.random_range(2..=8usize);
    let cards: Vec<usize> = (0..n).map(|_| rng.random_range(2..=4)).collect();
    let mut fg = FactorGraph::new(cards.clone()).unwrap();
    let mut next = 1;
    while next < n {
        let old = rng.random_range(0..next);
        let new_count = if next + 1 < n && rng.random_bool(0.4) {
            2
        } else {
            1
        };
        let mut vars = vec![old];
        for k in 0..new_count {
            vars.push(next + k);
        }
        next += new_count;
        // Shuffle the variable order inside the factor to exercise table layout.
        if rng.random_bool(0.5) {
            vars.reverse();
        }
        let size: usize = vars.iter().map(|&v| cards[v]).product();
        let t = random_table(&mut rng, size, extreme);
        fg.add_factor(vars, t).unwrap();
    }
    for _ in 0..rng.random_range(0..=n) {
        let v = rng.random_range(0..n);
        let t = random_table(&mut rng, cards[v], extreme);
        fg.add_factor(vec![v], t).unwrap();
    }
    fg
}

fn max_marginal_error(a: &[Vec<f64>], b: &[Vec<f64>]) -> f64 {
    a.iter()
        .zip(b)
        .flat_map(|(x, y)| x.iter().zip(y).map(|(p, q)| (p - q).abs()))
        .fold(0.0, f64::max)
}

#[test]
fn bp_is_exact_on_random_trees() {
    let mut checked = 0;
    for seed in 0..120u64 {
        let extreme = seed % 3 == 2;
        let fg = random_tree(seed, extreme);
        let exact = match exact_inference(&fg, 1 << 20) {
            Ok(e) => e,
            Err(MrfError::Inconsistent) => continue,
            Err(e) => panic!("seed {seed}: {e}"),
        };
        for (schedule, opts) in each_schedule(BpOptions {
            tolerance: 1e-13,
            max_iterations: 200,
            ..BpOptions::default()
        }) {
            let bp =
                loopy_bp(&fg, &opts).unwrap_or_else(|e| panic!("seed {seed} {schedule:?}: {e}"));
            assert!(bp.converged, "seed {seed} {schedule:?}: did not converge");
            let err = max_marginal_error(&bp.marginals, &exact.marginals);
            assert!(err < 1e-9, "seed {seed} {schedule:?}: marginal error {err}");
            let zerr = (bp.log_z_bethe - exact.log_z).abs();
            assert!(
                zerr < 1e-9 * exact.log_z.abs().max(1.0),
                "seed {seed} {schedule:?}: log Z {} vs exact {} (extreme = {extreme})",
                bp.log_z_bethe,
                exact.log_z
            );
        }
        checked += 1;
    }
    assert!(checked >= 50, "only {checked} consistent trees");
    println!("checked {checked} random trees (seeds 0..120)");
}

#[test]
fn tiny_potentials_do_not_underflow() {
    // A chain of 6 binary variables where every factor favours a state with
    // weight 1e-300 relative to the other: the product of the chain is far
    // below f64's range, yet the exact answer is representable.
    let n = 6;
    let mut fg = FactorGraph::new(vec![2; n]).unwrap();
    for i in 0..n - 1 {
        fg.add_factor(vec![i, i + 1], vec![1e-300, 0.0, 0.0, 1.0])
            .unwrap();
    }
    fg.add_factor(vec![0], vec![1.0, 1e-300]).unwrap();
    let exact = exact_inference(&fg, 1 << 10).unwrap();
    let bp = loopy_bp(&fg, &BpOptions::default()).unwrap();
    assert!(bp.converged);
    let err = max_marginal_error(&bp.marginals, &exact.marginals);
    assert!(err < 1e-12, "marginal error {err}");
    assert!((bp.log_z_bethe - exact.log_z).abs() < 1e-9 * exact.log_z.abs());
    // All-zeros-but-one: a hard constraint with exactly one consistent state.
    let mut fg = FactorGraph::new(vec![3, 3]).unwrap();
    let mut t = vec![0.0; 9];
    t[2 * 3 + 1] = 1e-300;
    fg.add_factor(vec![0, 1], t).unwrap();
    let bp = loopy_bp(&fg, &BpOptions::default()).unwrap();
    assert!((bp.marginals[0][2] - 1.0).abs() < 1e-15);
    assert!((bp.marginals[1][1] - 1.0).abs() < 1e-15);
    assert!((bp.log_z_bethe - (1e-300f64).ln()).abs() < 1e-9);
}

fn loopy_graph(seed: u64, kind: usize) -> FactorGraph {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let c = 3;
    let (n, edges): (usize, Vec<(usize, usize)>) = match kind {
        0 => {
            // Cycle of 4..=10.
            let n = rng.random_range(4..=10);
            (n, (0..n).map(|i| (i, (i + 1) % n)).collect())
        }
        _ => {
            // 3 × 3 grid.
            let mut e = Vec::new();
            for r in 0..3 {
                for q in 0..3 {
                    let i = r * 3 + q;
                    if q < 2 {
                        e.push((i, i + 1));
                    }
                    if r < 2 {
                        e.push((i, i + 3));
                    }
                }
            }
            (9, e)
        }
    };
    let mut fg = FactorGraph::new(vec![c; n]).unwrap();
    for (a, b) in edges {
        // Moderate couplings: log-potentials in [-0.5, 0.5].
        let t = (0..c * c)
            .map(|_| rng.random_range(-0.5f64..0.5).exp())
            .collect();
        fg.add_factor(vec![a, b], t).unwrap();
    }
    for i in 0..n {
        let t = (0..c)
            .map(|_| rng.random_range(-1.0f64..1.0).exp())
            .collect();
        fg.add_factor(vec![i], t).unwrap();
    }
    fg
}

#[test]
fn bp_error_is_small_on_small_loopy_graphs() {
    let mut worst_marg: f64 = 0.0;
    let mut worst_z: f64 = 0.0;
    for seed in 0..40u64 {
        let fg = loopy_graph(seed, (seed % 2) as usize);
        let exact = exact_inference(&fg, 1 << 20).unwrap();
        let bp = loopy_bp(&fg, &BpOptions::default()).unwrap();
        assert!(bp.converged, "seed {seed}: no convergence");
        worst_marg = worst_marg.max(max_marginal_error(&bp.marginals, &exact.marginals));
        worst_z = worst_z.max((bp.log_z_bethe - exact.log_z).abs());
    }
    println!(
        "loopy graphs (cycles ≤ 10, 3x3 grids, C = 3): max marginal error {worst_marg:.3e}, max |log Z error| {worst_z:.3e}"
    );
    assert!(worst_marg < 5e-3, "max marginal error {worst_marg}");
    assert!(worst_z < 1e-2, "max log Z error {worst_z}");
    // Loopy BP is not exact on these: the error must be visible.
    assert!(worst_marg > 1e-9);
}

#[test]
fn non_convergence_is_reported() {
    let fg = loopy_graph(7, 1);
    let full = loopy_bp(&fg, &BpOptions::default()).unwrap();
    assert!(full.converged && full.final_change < 1e-9);
    for (schedule, opts) in each_schedule(BpOptions {
        max_iterations: 2,
        ..BpOptions::default()
    }) {
        let short = loopy_bp(&fg, &opts).unwrap();
        assert!(!short.converged, "{schedule:?}");
        assert_eq!(short.iterations, 2);
        assert!(short.final_change >= 1e-9);
        // Heavy damping slows convergence: more sweeps than undamped.
        let undamped = loopy_bp(
            &fg,
            &BpOptions {
                schedule,
                ..BpOptions::default()
            },
        )
        .unwrap();
        let damped = loopy_bp(
            &fg,
            &BpOptions {
                damping: 0.9,
                schedule,
                ..BpOptions::default()
            },
        )
        .unwrap();
        assert!(damped.converged && undamped.converged);
        assert!(damped.iterations > undamped.iterations);
        let limited = loopy_bp(
            &fg,
            &BpOptions {
                damping: 0.9,
                max_iterations: undamped.iterations,
                schedule,
                ..BpOptions::default()
            },
        )
        .unwrap();
        assert!(!limited.converged);
        // Both converged runs reach the same fixed point.
        assert!(max_marginal_error(&damped.marginals, &undamped.marginals) < 1e-7);
    }
    // Frustrated strong anti-ferromagnetic triangle: plain parallel BP oscillates.
    let mut fg = FactorGraph::new(vec![2; 3]).unwrap();
    for (a, b) in [(0, 1), (1, 2), (0, 2)] {
        fg.add_factor(vec![a, b], vec![1e-3, 1.0, 1.0, 1e-3])
            .unwrap();
    }
    fg.add_factor(vec![0], vec![1.0, 2.0]).unwrap();
    let r = loopy_bp(
        &fg,
        &BpOptions {
            max_iterations: 50,
            schedule: Schedule::Parallel,
            ..BpOptions::default()
        },
    )
    .unwrap();
    println!(
        "frustrated triangle, parallel: converged {} after {} sweeps (last change {:.3e})",
        r.converged, r.iterations, r.final_change
    );
    assert_eq!(r.converged, r.final_change < 1e-9);
}

/// Convergence needs the largest change strictly below the tolerance: with the
/// tolerance set to exactly the last nonzero change of a chain (exact after a few
/// sweeps), BP takes one more sweep, whose change is 0, before it reports convergence.
#[test]
fn convergence_needs_a_change_strictly_below_the_tolerance() {
    let mut fg = FactorGraph::new(vec![2, 2, 2]).unwrap();
    fg.add_factor(vec![0], vec![3.0, 1.0]).unwrap();
    fg.add_factor(vec![0, 1], vec![2.0, 1.0, 1.0, 2.0]).unwrap();
    fg.add_factor(vec![1, 2], vec![2.0, 1.0, 1.0, 2.0]).unwrap();
    for (schedule, opts) in each_schedule(BpOptions::default()) {
        let change = |k: usize| {
            let r = loopy_bp(
                &fg,
                &BpOptions {
                    max_iterations: k,
                    ..opts
                },
            )
            .unwrap();
            r.final_change
        };
        // The sweeps' changes: positive up to sweep `last`, then exactly 0.
        let last = (1..10).take_while(|&k| change(k) > 0.0).last().unwrap();
        assert_eq!(change(last + 1), 0.0, "{schedule:?}");
        let c = change(last);
        let r = loopy_bp(
            &fg,
            &BpOptions {
                tolerance: c,
                ..opts
            },
        )
        .unwrap();
        assert!(r.converged, "{schedule:?}");
        assert_eq!(
            (r.iterations, r.final_change),
            (last + 1, 0.0),
            "{schedule:?}: tolerance {c}"
        );
    }
}

#[test]
fn invalid_inputs_are_rejected() {
    let mut fg = FactorGraph::new(vec![2, 2]).unwrap();
    assert!(fg.add_factor(vec![0, 0], vec![1.0; 4]).is_err());
    assert!(fg.add_factor(vec![0, 2], vec![1.0; 4]).is_err());
    assert!(fg.add_factor(vec![0, 1], vec![1.0; 3]).is_err());
    assert!(fg.add_factor(vec![0], vec![1.0, f64::NAN]).is_err());
    assert!(fg.add_factor(vec![0], vec![1.0, -1.0]).is_err());
    assert!(FactorGraph::new(vec![2, 0]).is_err());
    fg.add_factor(vec![0, 1], vec![1.0; 4]).unwrap();
    for bad in [
        BpOptions {
            damping: 1.0,
            ..BpOptions::default()
        },
        BpOptions {
            tolerance: 0.0,
            ..BpOptions::default()
        },
        BpOptions {
            max_iterations: 0,
            ..BpOptions::default()
        },
    ] {
        assert!(matches!(loopy_bp(&fg, &bad), Err(MrfError::BadOptions(_))));
    }
    // Contradictory unaries: BP must report it, not return NaN.
    let mut fg = FactorGraph::new(vec![2, 2]).unwrap();
    fg.add_factor(vec![0, 1], vec![1.0, 0.0, 0.0, 1.0]).unwrap();
    fg.add_factor(vec![0], vec![1.0, 0.0]).unwrap();
    fg.add_factor(vec![1], vec![0.0, 1.0]).unwrap();
    assert!(matches!(
        loopy_bp(&fg, &BpOptions::default()),
        Err(MrfError::Contradiction { .. })
    ));
}

/// Damping is pinned to its documented form: one parallel sweep on a single pairwise
/// factor `ψ` over two binary variables (the message into variable 1 starts uniform and
/// its update is `ψ`'s normalised column sums `u`) leaves variable 1's belief at `(1 −
/// d)·u + d·(½, ½)`; swapping `d` and `1 − d`, or dropping the old message, fails.
#[test]
fn damping_mixes_the_update_with_the_old_message_as_documented() {
    let mut fg = FactorGraph::new(vec![2, 2]).unwrap();
    // Column sums 1.6 and 0.4: u = (0.8, 0.2).
    fg.add_factor(vec![0, 1], vec![0.9, 0.1, 0.7, 0.3]).unwrap();
    for d in [0.0, 0.3, 0.6] {
        let r = loopy_bp(
            &fg,
            &BpOptions {
                damping: d,
                max_iterations: 1,
                schedule: Schedule::Parallel,
                ..BpOptions::default()
            },
        )
        .unwrap();
        let want = [(1.0 - d) * 0.8 + d * 0.5, (1.0 - d) * 0.2 + d * 0.5];
        let got = &r.marginals[1];
        assert!(
            (got[0] - want[0]).abs() < 1e-12 && (got[1] - want[1]).abs() < 1e-12,
            "damping {d}: {got:?} vs {want:?}"
        );
    }
}

/// `opts` with each schedule in turn: every BP property is checked under both.
fn each_schedule(opts: BpOptions) -> [(Schedule, BpOptions); 2] {
    [Schedule::Parallel, Schedule::Sequential]
        .map(|schedule| (schedule, BpOptions { schedule, ..opts }))
}

/// Messages far below `f64`'s range take the log path even when no potential is
/// extreme: variable 0's evidence (three factors of `1e-110`) leaves its state 1 at
/// `1e-330`, below the smallest `f64`, yet an identity factor and variable 1's hard
/// evidence make state 1 the only consistent one. Linear-space messages would round it
/// to 0 and report a contradiction.
#[test]
fn messages_below_the_f64_range_take_the_log_path() {
    let mut fg = FactorGraph::new(vec![2, 2]).unwrap();
    for _ in 0..3 {
        fg.add_factor(vec![0], vec![1.0, 1e-110]).unwrap();
    }
    fg.add_factor(vec![0, 1], vec![1.0, 0.0, 0.0, 1.0]).unwrap();
    fg.add_factor(vec![1], vec![0.0, 1.0]).unwrap();
    for (schedule, opts) in each_schedule(BpOptions::default()) {
        let bp = loopy_bp(&fg, &opts).unwrap_or_else(|e| panic!("{schedule:?}: {e}"));
        assert_eq!(bp.marginals[0], vec![0.0, 1.0], "{schedule:?}");
        assert_eq!(bp.marginals[1], vec![0.0, 1.0], "{schedule:?}");
    }
}

/// A factor whose message has no positive entry is reported as a contradiction naming
/// the factor (not turned into NaN messages): variable 1 must be in state 0, where the
/// factor gives variable 0 no weight at all.
#[test]
fn a_message_with_no_mass_is_a_contradiction() {
    let mut fg = FactorGraph::new(vec![2, 2]).unwrap();
    fg.add_factor(vec![1], vec![1.0, 0.0]).unwrap();
    fg.add_factor(vec![0, 1], vec![0.0, 1.0, 0.0, 1.0]).unwrap();
    for (schedule, opts) in each_schedule(BpOptions::default()) {
        let r = loopy_bp(&fg, &opts);
        assert!(
            matches!(r, Err(MrfError::Contradiction { .. })),
            "{schedule:?}: {r:?}"
        );
    }
}
