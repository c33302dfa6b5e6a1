//! The firmware's fixed evidence and labels, reproducible anywhere: a SplitMix64
//! stream from a documented seed, turned into `f32` values without rounding (every
//! value is `k · 2⁻²⁴` for an integer `1 ≤ k ≤ 2²⁴`). `tests/mcu_qemu/` includes
//! this file to recompute the same inputs on the host.

/// Seed of the evidence stream of map `i` (in the firmware's map order) is
/// `SEED + i`.
pub const SEED: u64 = 0x6772_6170_6873_706e; // "graphspn"

/// SplitMix64 (Steele, Lea & Flood 2014): a tiny seeded generator.
pub struct SplitMix64(pub u64);

impl SplitMix64 {
    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `(0, 1]`, exactly representable in `f32`.
    pub fn unit_f32(&mut self) -> f32 {
        ((self.next_u64() >> 40) + 1) as f32 * (1.0 / 16_777_216.0)
    }
}

/// Fills `rows` (one row of `classes` likelihoods per place, flattened) and
/// `labels` (one per place; `unknown` for unlabelled places) from seed `seed`:
/// one place in 8 has no evidence (a row of ones, like a placeholder), the others
/// get independent values in `(0, 1]`; one place in 3 is labelled with a random
/// class (for `labelled_log_likelihood`).
pub fn fill(seed: u64, classes: usize, rows: &mut [f32], labels: &mut [u16], unknown: u16) {
    let mut rng = SplitMix64(seed);
    for row in rows.chunks_mut(classes) {
        let no_evidence = rng.next_u64().is_multiple_of(8);
        for v in row.iter_mut() {
            *v = if no_evidence { 1.0 } else { rng.unit_f32() };
        }
    }
    for l in labels.iter_mut() {
        let r = rng.next_u64();
        *l = if r.is_multiple_of(3) {
            ((r >> 8) % classes as u64) as u16
        } else {
            unknown
        };
    }
}

/// Number of streaming steps the firmware runs per map (after its four stateless
/// calls): even steps time `observe` + `marginals`, odd steps `observe` +
/// `marginal(place)`.
pub const STEPS: u64 = 16;

/// The observation of streaming step `index` of the map with evidence seed `seed`:
/// writes a row of likelihoods in `(0, 1]` into `row` and returns the place it is
/// for (uniform over `places`).
pub fn step(seed: u64, index: u64, places: usize, row: &mut [f32]) -> usize {
    let mut rng = SplitMix64(seed ^ (index + 1).wrapping_mul(0xD1B5_4A32_D192_ED03));
    let place = (rng.next_u64() % places as u64) as usize;
    for v in row.iter_mut() {
        *v = rng.unit_f32();
    }
    place
}

/// The place of the adversarial fusion sequence (every map has more places).
pub const FUSION_PLACE: usize = 11;

/// The adversarial fusion sequence the firmware runs on a new state of each map, phase
/// after phase at [`FUSION_PLACE`]: `(class, other, count)` is `count` observations
/// favouring `class` (see [`favouring`]). Net evidence after each phase: class 2 by
/// 9^300, class 3 by 9^100, class 2 by 9^50 — a renormalised `f32` row would have
/// locked the place at class 2 after the first phase.
pub const FUSION: [(usize, usize, u32); 3] = [(2, 3, 300), (3, 2, 400), (2, 3, 150)];

/// An observation favouring `class` (0.9) over `other` (0.1) and the rest (0.05).
pub fn favouring(class: usize, other: usize, row: &mut [f32]) {
    for (k, v) in row.iter_mut().enumerate() {
        *v = if k == class {
            0.9
        } else if k == other {
            0.1
        } else {
            0.05
        };
    }
}
