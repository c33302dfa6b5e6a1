//! The streaming state of generated tree-mixture code: every forest's stored upward
//! pass, kept current one place at a time, and each place's fused observations in an
//! exact form.
//!
//! # Memory
//!
//! Per forest and place one row (the message to the parent; a root's belief) and one
//! exponent; per place its evidence row (what `evidence()` returns) and its fused
//! observations ([`Fused`]: per class a mantissa and a `u16` deficit, and two `i32`
//! exponents), and the sum of those rows' shifts (so `log_likelihood` needs no pass over
//! the places). Bytes: `T·N·(K·size_of(V) + 4) + N·(C·(2·size_of(scalar) + 2) + 8) + 4·T
//! + 12`, plus alignment padding.
//!
//! # Exact fusion (`observe`)
//!
//! The fused row of a place is the product of its observations, kept exactly by
//! [`Fused`] (no underflow, no class locked at 0; see its module). The row the inference
//! uses (and `evidence()` returns) is that product scaled by a power of two (largest
//! entry in `[1, 2)`, classes below the smallest normal value `2^MIN_EXP` of it set
//! to 0: the row holds every class that a normal number can, and no subnormal), and
//! `log_likelihood` adds the dropped power back: it is the log-likelihood of the
//! product of every observation. `labelled_log_likelihood` reads a labelled place's
//! label from the fused form where its row holds 0 ([`FusedLabels`]): a labelled
//! place's factor is that one value.
//!
//! # Costs
//!
//! An update recomputes the place's path to the root in every forest: `Σ_t (depth_t(v)
//! + 1)` beliefs and matrix–vector products. `log_likelihood` reads the roots (`O(T·C)`),
//! `marginal(place)` walks each forest from the root to the place (`O(T·height·C²)`),
//! `marginals` is one downward pass per forest (`O(T·N·C²)`).

use super::super::{Acc, Fused, Lanes, Real, check_row, check_rows, mix, shift_ln, shift_sum};
use super::pass::{
    add_marginal, cached, full_below, log_of_mix, normalise_rows, over_z, tree_downward,
    tree_upward, values, with_factors,
};
use super::{Forest, FusedLabels, Rows, TreeModel, belief, hsum, up_message};
use crate::EvidenceError;

/// The caller-owned cache of a compiled tree mixture (see the module docs); all zeros
/// when new (a `static` one sits in `.bss`): rows of ones are written by the first call
/// that needs them.
#[derive(Clone)]
pub struct TreeState<V: Lanes, const C: usize, const K: usize, const N: usize, const T: usize> {
    rows: [[V::Scalar; C]; N],
    fused: [Fused<V::Scalar, C>; N],
    /// `Σ fused[q].shift()` over the places (`ln_shift` without a pass over them).
    shift: i64,
    msg: [[[V; K]; N]; T],
    exp: [[i32; N]; T],
    total: [i32; T],
    ready: bool,
}

impl<V: Lanes, const C: usize, const K: usize, const N: usize, const T: usize> Default
    for TreeState<V, C, K, N, T>
{
    fn default() -> Self {
        Self::new()
    }
}

/// `place`'s id, or `PlaceOutOfRange` when `place` is not a place index.
fn place_id<const N: usize>(ids: &[u32; N], place: usize) -> Result<u32, EvidenceError> {
    ids.get(place)
        .copied()
        .ok_or(EvidenceError::PlaceOutOfRange { place, places: N })
}

impl<V: Lanes, const C: usize, const K: usize, const N: usize, const T: usize>
    TreeState<V, C, K, N, T>
{
    /// A state without evidence (all zeros in memory).
    pub const fn new() -> Self {
        TreeState {
            rows: [[<V::Scalar as Real>::ZERO; C]; N],
            fused: [Fused::ZERO; N],
            shift: 0,
            msg: [[[V::ZERO; K]; N]; T],
            exp: [[0; N]; T],
            total: [0; T],
            ready: false,
        }
    }

    /// Whether the state holds rows (`false` until the first update or query: then
    /// every row is a row of ones).
    pub fn is_ready(&self) -> bool {
        self.ready
    }

    /// The evidence rows (meaningful once [`TreeState::is_ready`]).
    pub fn rows(&self) -> &[[V::Scalar; C]; N] {
        &self.rows
    }

    /// Rows of ones and every forest evaluated, on first use.
    fn fresh(&mut self, m: &TreeModel<V, C, K>) {
        if !self.ready {
            let one = V::Scalar::ONE;
            self.rows = [[one; C]; N];
            self.fused = [Fused::ONES; N];
            self.shift = 0;
            self.refresh(m);
        }
    }

    /// Calls `each(rows, forest, messages, exponents, total)` for every forest.
    fn each_forest(
        &mut self,
        m: &TreeModel<V, C, K>,
        mut each: impl FnMut(
            &Rows<'_, V, C, K, N>,
            &Forest<V::Scalar>,
            &mut [[V; K]; N],
            &mut [i32; N],
            &mut i32,
        ),
    ) {
        let rows = Rows {
            m,
            e: &self.rows,
            labels: None,
        };
        for (((f, msgs), exps), tot) in m
            .forests
            .iter()
            .zip(self.msg.iter_mut())
            .zip(self.exp.iter_mut())
            .zip(self.total.iter_mut())
        {
            each(&rows, f, msgs, exps, tot);
        }
    }

    /// Every forest's stored upward pass from the current rows.
    fn refresh(&mut self, m: &TreeModel<V, C, K>) {
        self.each_forest(m, |rows, f, msgs, exps, tot| {
            *tot = tree_upward(m, rows, f, msgs, Some(exps)).1;
        });
        self.ready = true;
    }

    /// Recomputes the path from `place` to its root in every forest.
    fn update(&mut self, m: &TreeModel<V, C, K>, place: usize) {
        self.each_forest(m, |rows, f, msgs, exps, tot| {
            let mut a = place;
            for _ in 0..N {
                let (b, eb) = belief(rows, f, msgs, a);
                let parent = f.parent_of(a);
                let root = usize::from(parent) >= N;
                let (out, ev) = if root {
                    (m.root_belief(b), eb)
                } else {
                    let (mm, em) = up_message(m, &b);
                    (mm, eb.wrapping_add(em))
                };
                if let (Some(s), Some(x)) = (msgs.get_mut(a), exps.get_mut(a)) {
                    *s = out;
                    *tot = tot.wrapping_add(ev).wrapping_sub(*x);
                    *x = ev;
                }
                if root {
                    break;
                }
                a = usize::from(parent);
            }
        });
    }

    /// Stores the row and fused form of `place` and updates the forests.
    fn store(
        &mut self,
        m: &TreeModel<V, C, K>,
        place: usize,
        row: [V::Scalar; C],
        fused: Fused<V::Scalar, C>,
    ) {
        if let (Some(r), Some(f)) = (self.rows.get_mut(place), self.fused.get_mut(place)) {
            *r = row;
            self.shift += i64::from(fused.shift()) - i64::from(f.shift());
            *f = fused;
        }
        self.update(m, place);
    }

    /// Sets the evidence row of `place` (kept as given) and updates the forests. An
    /// invalid row is rejected and nothing changes.
    pub fn set_evidence(
        &mut self,
        m: &TreeModel<V, C, K>,
        ids: &[u32; N],
        place: usize,
        row: &[V::Scalar; C],
    ) -> Result<(), EvidenceError> {
        check_row(row, place, place_id(ids, place)?)?;
        self.fresh(m);
        self.store(m, place, *row, Fused::of(row));
        Ok(())
    }

    /// Fuses an observation into the place's row exactly (see the module docs) and
    /// updates the forests. An invalid row, or one leaving the place no class, is
    /// rejected and nothing changes.
    pub fn observe(
        &mut self,
        m: &TreeModel<V, C, K>,
        ids: &[u32; N],
        place: usize,
        row: &[V::Scalar; C],
    ) -> Result<(), EvidenceError> {
        let id = place_id(ids, place)?;
        check_row(row, place, id)?;
        self.fresh(m);
        let Some(old) = self.fused.get(place) else {
            return Ok(());
        };
        let (fused, fused_row) =
            old.observe(row, V::Scalar::MIN_EXP)
                .ok_or(EvidenceError::NoMass {
                    place,
                    place_id: u64::from(id),
                })?;
        self.store(m, place, fused_row, fused);
        Ok(())
    }

    /// Removes the evidence of `place` (a row of ones) and updates the forests.
    pub fn clear_evidence(
        &mut self,
        m: &TreeModel<V, C, K>,
        ids: &[u32; N],
        place: usize,
    ) -> Result<(), EvidenceError> {
        place_id(ids, place)?;
        self.fresh(m);
        self.store(m, place, [V::Scalar::ONE; C], Fused::ONES);
        Ok(())
    }

    /// Replaces every row (checked first: on error nothing changes) and re-evaluates
    /// every forest.
    pub fn set_all(
        &mut self,
        m: &TreeModel<V, C, K>,
        ids: &[u32; N],
        e: &[[V::Scalar; C]; N],
    ) -> Result<(), EvidenceError> {
        check_rows(e, ids)?;
        self.rows = *e;
        for (r, f) in e.iter().zip(self.fused.iter_mut()) {
            *f = Fused::of(r);
        }
        self.shift = shift_sum(&self.fused);
        self.refresh(m);
        Ok(())
    }

    /// Every forest's value over `Z_t`, from the cache.
    fn values(&self, m: &TreeModel<V, C, K>) -> [Acc<V::Scalar>; T] {
        let mut accs = [Acc::ONE; T];
        for (((a, f), msgs), &tot) in accs
            .iter_mut()
            .zip(m.forests)
            .zip(&self.msg)
            .zip(&self.total)
        {
            let mut acc = Acc::ONE;
            for &r in f.roots {
                if let Some(b) = msgs.get(usize::from(r)) {
                    acc.mul(hsum(b));
                }
            }
            *a = over_z(acc, tot, f);
        }
        accs
    }

    /// `ln S` and the forests' weights in the marginals (posterior `P(t | α)`, or `1`
    /// each when the model averages).
    fn mixed(
        &mut self,
        m: &TreeModel<V, C, K>,
    ) -> Result<(V::Scalar, [V::Scalar; T]), EvidenceError> {
        self.fresh(m);
        match mix(&self.values(m)) {
            Some((l, w)) if l > V::Scalar::NEG_INFINITY => Ok((
                l + self.ln_shift(m),
                if m.average { [V::Scalar::ONE; T] } else { w },
            )),
            _ => Err(EvidenceError::ZeroLikelihood),
        }
    }

    /// `ln` of the factor by which the stored rows (to the power `γ`) lie below the
    /// fused observations' (see [`super::super::ln_shift`]); `0` when no row was fused by
    /// `observe`.
    pub fn ln_shift(&self, m: &TreeModel<V, C, K>) -> V::Scalar {
        if self.ready {
            shift_ln(self.shift * i64::from(m.gamma))
        } else {
            V::Scalar::ZERO
        }
    }

    /// `ln S` of the fused observations with every place of `labels` restricted to its
    /// label (`u16::MAX`: the whole row), by a full value pass over the forests (`H` >
    /// the height + 1); a label that the state's row reads as 0 (fused below the
    /// smallest normal value of the best class) counts with its exact fused value.
    pub fn labelled_log_likelihood<const H: usize>(
        &mut self,
        m: &TreeModel<V, C, K>,
        labels: &[u16; N],
    ) -> Result<V::Scalar, EvidenceError> {
        self.fresh(m);
        let src = FusedLabels {
            rows: Rows {
                m,
                e: &self.rows,
                labels: Some(labels),
            },
            fused: &self.fused,
        };
        let accs = if m.cache.values {
            cached::<V, K, N, _>(&src, |s| values::<V, C, K, N, H, T>(m, s, false))
        } else {
            values::<V, C, K, N, H, T>(m, &src, false)
        };
        Ok(log_of_mix(&accs)? + self.ln_shift(m))
    }

    /// `ln S` of the fused observations, from the cache (`O(T·C)`).
    pub fn log_likelihood(&mut self, m: &TreeModel<V, C, K>) -> Result<V::Scalar, EvidenceError> {
        self.mixed(m).map(|(l, _)| l)
    }

    /// The marginals of every place from the cache (one downward pass per forest, a
    /// stack of `H` rows); returns `ln S`.
    pub fn marginals<const H: usize>(
        &mut self,
        m: &TreeModel<V, C, K>,
        out: &mut [[V::Scalar; C]; N],
    ) -> Result<V::Scalar, EvidenceError> {
        let (l, w) = self.mixed(m)?;
        *out = [[V::Scalar::ZERO; C]; N];
        with_factors(m, &self.rows, None, m.cache.state, |src| {
            for ((f, msgs), &wt) in m.forests.iter().zip(&self.msg).zip(&w) {
                tree_downward::<V, C, K, N, H>(m, src, f, msgs, wt, out);
            }
        });
        normalise_rows(out);
        Ok(l)
    }

    /// The marginal of one place from the cache: each forest walked from the root down
    /// to the place (`H` > the height + 1).
    pub fn marginal<const H: usize>(
        &mut self,
        m: &TreeModel<V, C, K>,
        ids: &[u32; N],
        place: usize,
        out: &mut [V::Scalar; C],
    ) -> Result<(), EvidenceError> {
        place_id(ids, place)?;
        let (_, w) = self.mixed(m)?;
        *out = [V::Scalar::ZERO; C];
        let rows = Rows {
            m,
            e: &self.rows,
            labels: None,
        };
        for ((f, msgs), &wt) in m.forests.iter().zip(&self.msg).zip(&w) {
            // The path from the place up to its root.
            let mut path = [0u16; H];
            let mut len = 0;
            let mut a = place as u16;
            for p in path.iter_mut() {
                *p = a;
                len += 1;
                a = f.parent_of(usize::from(a));
                if usize::from(a) >= N {
                    break;
                }
            }
            let mut steps = path.iter().take(len).rev();
            let Some(full) = steps.next().and_then(|&r| msgs.get(usize::from(r))) else {
                continue;
            };
            let mut full = *full;
            for &c in steps {
                full = full_below(m, &rows, f, msgs, usize::from(c), &full);
            }
            add_marginal(out, &full, wt);
        }
        let mut one = [*out];
        normalise_rows(&mut one);
        let [row] = one;
        *out = row;
        Ok(())
    }
}
