//! A general discrete factor graph: variables with finitely many states and
//! non-negative factors given as dense tables.

use super::MrfError;
use std::sync::Arc;

/// Largest number of entries a single factor table may have.
pub const MAX_FACTOR_ENTRIES: usize = 1 << 24;

/// One factor: the variables it touches and its dense, non-negative table.
///
/// The table is row-major over `vars` in the order given: the *last* variable
/// varies fastest. For `vars = [a, b, c]` with cardinalities `(Ca, Cb, Cc)` the
/// entry of `(xa, xb, xc)` is at `(xa * Cb + xb) * Cc + xc`.
#[derive(Clone, Debug, PartialEq)]
pub struct Factor {
    vars: Vec<usize>,
    table: Arc<[f64]>,
}

impl Factor {
    /// Variables of the factor, in table order.
    pub fn vars(&self) -> &[usize] {
        &self.vars
    }

    /// The dense table (row-major, last variable fastest).
    pub fn table(&self) -> &[f64] {
        &self.table
    }

    /// The shared table (factors added with the same `Arc` share one allocation).
    pub fn shared_table(&self) -> &Arc<[f64]> {
        &self.table
    }
}

/// A discrete factor graph: `cards[i]` states for variable `i`, and factors.
///
/// The unnormalised score of an assignment `x` is `∏_a f_a(x_a)`; the partition
/// function is `Z = Σ_x ∏_a f_a(x_a)`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FactorGraph {
    cards: Vec<usize>,
    factors: Vec<Factor>,
}

impl FactorGraph {
    /// A factor graph with the given variable cardinalities (each ≥ 1) and no factors.
    pub fn new(cards: Vec<usize>) -> Result<Self, MrfError> {
        if let Some(i) = cards.iter().position(|&c| c == 0) {
            return Err(MrfError::ZeroCardinality { var: i });
        }
        Ok(FactorGraph {
            cards,
            factors: Vec::new(),
        })
    }

    /// Number of variables.
    pub fn num_vars(&self) -> usize {
        self.cards.len()
    }

    /// Cardinality of every variable.
    pub fn cards(&self) -> &[usize] {
        &self.cards
    }

    /// All factors, in insertion order (the factor id is the index).
    pub fn factors(&self) -> &[Factor] {
        &self.factors
    }

    /// Adds a factor over distinct, existing `vars` (at least one) with a table of
    /// `∏ cards` finite, non-negative entries; returns its factor id.
    pub fn add_factor(&mut self, vars: Vec<usize>, table: Vec<f64>) -> Result<usize, MrfError> {
        self.add_factor_shared(vars, table.into())
    }

    /// [`FactorGraph::add_factor`] with a shared table: many factors (e.g. one
    /// potential on every edge) can use one allocation, and belief propagation
    /// prepares each distinct table only once.
    pub fn add_factor_shared(
        &mut self,
        vars: Vec<usize>,
        table: Arc<[f64]>,
    ) -> Result<usize, MrfError> {
        let id = self.factors.len();
        if vars.is_empty() {
            return Err(MrfError::EmptyFactor { factor: id });
        }
        let mut size: usize = 1;
        for (k, &v) in vars.iter().enumerate() {
            if v >= self.cards.len() {
                return Err(MrfError::UnknownVariable {
                    factor: id,
                    var: v,
                    num_vars: self.cards.len(),
                });
            }
            if vars[..k].contains(&v) {
                return Err(MrfError::RepeatedVariable { factor: id, var: v });
            }
            size = size
                .checked_mul(self.cards[v])
                .filter(|&s| s <= MAX_FACTOR_ENTRIES)
                .ok_or(MrfError::FactorTooLarge { factor: id })?;
        }
        if table.len() != size {
            return Err(MrfError::TableSize {
                factor: id,
                expected: size,
                found: table.len(),
            });
        }
        if let Some(e) = table.iter().position(|x| !x.is_finite() || *x < 0.0) {
            return Err(MrfError::BadPotential {
                factor: id,
                entry: e,
                value: table[e],
            });
        }
        self.factors.push(Factor { vars, table });
        Ok(id)
    }

    /// Natural log of the unnormalised score `∏_a f_a(x_a)` of a full assignment
    /// (`-inf` when some factor is zero there).
    pub fn log_score(&self, assignment: &[usize]) -> Result<f64, MrfError> {
        if assignment.len() != self.cards.len() {
            return Err(MrfError::AssignmentLength {
                expected: self.cards.len(),
                found: assignment.len(),
            });
        }
        if let Some(i) = (0..assignment.len()).find(|&i| assignment[i] >= self.cards[i]) {
            return Err(MrfError::StateOutOfRange {
                var: i,
                state: assignment[i],
                card: self.cards[i],
            });
        }
        let mut s = 0.0;
        for f in &self.factors {
            let mut idx = 0;
            for &v in &f.vars {
                idx = idx * self.cards[v] + assignment[v];
            }
            s += f.table[idx].ln();
        }
        Ok(s)
    }
}

/// Exact marginals and log partition function by enumerating every joint state.
#[derive(Clone, Debug, PartialEq)]
pub struct ExactResult {
    /// `marginals[i][s] = P(x_i = s)`.
    pub marginals: Vec<Vec<f64>>,
    /// Natural log of `Z` (computed with a running log-sum-exp; relative error
    /// about `1e-15 × number of states`).
    pub log_z: f64,
}

/// Brute-force inference by enumeration, for testing: exponential in the number
/// of variables, refused above `max_states` joint states.
pub fn exact_inference(fg: &FactorGraph, max_states: usize) -> Result<ExactResult, MrfError> {
    let mut total: usize = 1;
    for &c in &fg.cards {
        total = total
            .checked_mul(c)
            .filter(|&t| t <= max_states)
            .ok_or(MrfError::TooManyStates { max_states })?;
    }
    // First pass: the maximum log score (for a stable log-sum-exp).
    let n = fg.num_vars();
    let mut x = vec![0usize; n];
    let mut scores = Vec::with_capacity(total);
    for _ in 0..total {
        scores.push(fg.log_score(&x)?);
        odometer(&mut x, &fg.cards);
    }
    let m = scores.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    if m == f64::NEG_INFINITY {
        return Err(MrfError::Inconsistent);
    }
    let mut marg: Vec<Vec<f64>> = fg.cards.iter().map(|&c| vec![0.0; c]).collect();
    let mut z = 0.0;
    x.iter_mut().for_each(|v| *v = 0);
    for &s in &scores {
        let w = (s - m).exp();
        z += w;
        for i in 0..n {
            marg[i][x[i]] += w;
        }
        odometer(&mut x, &fg.cards);
    }
    for row in &mut marg {
        row.iter_mut().for_each(|p| *p /= z);
    }
    Ok(ExactResult {
        marginals: marg,
        log_z: m + z.ln(),
    })
}

/// Advances `x` to the next joint state (last variable fastest); wraps to all zeros.
pub(crate) fn odometer(x: &mut [usize], cards: &[usize]) {
    for k in (0..x.len()).rev() {
        x[k] += 1;
        if x[k] < cards[k] {
            return;
        }
        x[k] = 0;
    }
}

/// A dense table over sorted variables with a log scale: value = `t[idx] · e^ls`.
struct Table {
    vars: Vec<usize>,
    t: Vec<f64>,
    ls: f64,
}

/// Multiplies `tabs` and sums out `elim` (if any); the result is scaled to max 1.
fn product_sum_out(
    tabs: &[Table],
    elim: Option<usize>,
    cards: &[usize],
    max_entries: usize,
) -> Result<Table, MrfError> {
    let mut all: Vec<usize> = tabs.iter().flat_map(|t| t.vars.iter().copied()).collect();
    all.sort_unstable();
    all.dedup();
    let mut size: usize = 1;
    for &v in &all {
        size = size
            .checked_mul(cards[v])
            .filter(|&s| s <= max_entries)
            .ok_or(MrfError::TooManyStates {
                max_states: max_entries,
            })?;
    }
    let out_vars: Vec<usize> = all.iter().copied().filter(|&v| Some(v) != elim).collect();
    let out_size: usize = out_vars.iter().map(|&v| cards[v]).product();
    // Strides of each table (and of the output) over the positions of `all`.
    let stride_of = |vars: &[usize]| -> Vec<usize> {
        let mut st = vec![0usize; all.len()];
        let mut s = 1;
        for &v in vars.iter().rev() {
            let p = all.iter().position(|&x| x == v).unwrap_or(0);
            st[p] = s;
            s *= cards[v];
        }
        st
    };
    let strides: Vec<Vec<usize>> = tabs.iter().map(|t| stride_of(&t.vars)).collect();
    let out_stride = stride_of(&out_vars);
    let all_cards: Vec<usize> = all.iter().map(|&v| cards[v]).collect();
    let mut out = vec![0.0; out_size];
    let mut x = vec![0usize; all.len()];
    for _ in 0..size {
        let mut p = 1.0;
        for (tab, st) in tabs.iter().zip(&strides) {
            let idx: usize = x.iter().zip(st).map(|(a, b)| a * b).sum();
            p *= tab.t[idx];
        }
        let o: usize = x.iter().zip(&out_stride).map(|(a, b)| a * b).sum();
        out[o] += p;
        odometer(&mut x, &all_cards);
    }
    let mx = out.iter().cloned().fold(0.0, f64::max);
    let mut ls: f64 = tabs.iter().map(|t| t.ls).sum();
    if mx > 0.0 {
        out.iter_mut().for_each(|v| *v /= mx);
        ls += mx.ln();
    }
    Ok(Table {
        vars: out_vars,
        t: out,
        ls,
    })
}

/// Exact marginals and `ln Z` by variable elimination (greedy min-degree order,
/// one elimination run per variable), for graphs too large to enumerate but of
/// small treewidth. Tables are rescaled to max 1 after every step (log scale
/// kept separately), so nothing underflows; relative error about `1e-13`.
/// Refused ([`MrfError::TooManyStates`]) when an intermediate table would
/// exceed `max_entries`.
pub fn variable_elimination(fg: &FactorGraph, max_entries: usize) -> Result<ExactResult, MrfError> {
    let cards = fg.cards();
    let n = fg.num_vars();
    // Factors with their variables sorted (tables re-indexed).
    let base: Vec<Table> = fg
        .factors()
        .iter()
        .map(|f| {
            let mut sorted = f.vars().to_vec();
            sorted.sort_unstable();
            let single = Table {
                vars: f.vars().to_vec(),
                t: f.table().to_vec(),
                ls: 0.0,
            };
            if sorted == f.vars() {
                Ok(single)
            } else {
                product_sum_out(&[single], None, cards, max_entries)
            }
        })
        .collect::<Result<_, _>>()?;
    let mut marginals = Vec::with_capacity(n);
    let mut log_z = 0.0;
    for q in 0..n {
        let mut tabs: Vec<Table> = base
            .iter()
            .map(|t| Table {
                vars: t.vars.clone(),
                t: t.t.clone(),
                ls: t.ls,
            })
            .collect();
        let mut left: Vec<usize> = (0..n).filter(|&v| v != q).collect();
        while !left.is_empty() {
            // Min-degree: the variable whose elimination builds the smallest table.
            let (k, &v) = left
                .iter()
                .enumerate()
                .min_by_key(|&(_, &v)| {
                    let mut nb: Vec<usize> = tabs
                        .iter()
                        .filter(|t| t.vars.contains(&v))
                        .flat_map(|t| t.vars.iter().copied())
                        .collect();
                    nb.sort_unstable();
                    nb.dedup();
                    (nb.len(), v)
                })
                .expect("left is not empty");
            left.swap_remove(k);
            let (with, without): (Vec<Table>, Vec<Table>) =
                tabs.into_iter().partition(|t| t.vars.contains(&v));
            tabs = without;
            if with.is_empty() {
                // A variable in no factor contributes a factor of its cardinality.
                tabs.push(Table {
                    vars: Vec::new(),
                    t: vec![1.0],
                    ls: (cards[v] as f64).ln(),
                });
            } else {
                tabs.push(product_sum_out(&with, Some(v), cards, max_entries)?);
            }
        }
        let fin = product_sum_out(&tabs, None, cards, max_entries)?;
        // `fin` is over [q] (or empty when q is in no factor).
        let row: Vec<f64> = if fin.vars.is_empty() {
            vec![fin.t[0]; cards[q]]
        } else {
            fin.t.clone()
        };
        let z: f64 = row.iter().sum();
        if z <= 0.0 {
            return Err(MrfError::Inconsistent);
        }
        if q == 0 {
            log_z = fin.ls + z.ln();
        }
        marginals.push(row.iter().map(|v| v / z).collect());
    }
    Ok(ExactResult { marginals, log_z })
}
