//! Work that cannot fit is refused before it is attempted.
//!
//! Every command that builds something whose size grows with the map (decompositions,
//! the component-wise evaluator, the explicit instance SPN, a tree mixture's trees, the
//! generated code) states it as a [`Work`] before it reads the map. The map is then
//! read with [`read_map_within`]: the loaders count the places in the file (a JSON
//! map's `places`, the lines of a COLD `nodes.dat`) and stop keeping them past
//! [`Budget::max_places`], so a map too large for the work is refused before its graph
//! is built, with one line naming the flag that sets the work's size and the estimate.
//! Estimates are upper bounds measured on synthetic floors (`graphspn generate`), within
//! a factor of about 2; the limit is [`MEMORY_LIMIT`].

use std::path::Path;

use anyhow::{Result, bail};
use graphspn_compiler::map::MapError;

use super::map_input::{LoadedMap, read_map_limited};

/// Largest memory (bytes) a host command may plan to use before it refuses with an
/// estimate: 4 GiB.
pub const MEMORY_LIMIT: u128 = 4 << 30;

/// `bytes` as gigabytes, e.g. `4.3 GB`.
pub fn gb(bytes: u128) -> String {
    format!("{:.1} GB", bytes as f64 / 1e9)
}

/// What a command is about to build for a map.
#[derive(Clone, Copy, Debug)]
pub enum Work {
    /// Only the decompositions: the best `count` of `candidates` seeded partitions
    /// (`decompose`, `compile`). Measured: 60 bytes per place and decomposition kept
    /// (3 candidates each) at 100,000 places.
    Decompositions {
        /// Decompositions kept.
        count: usize,
        /// Candidates drawn.
        candidates: usize,
    },
    /// The decompositions and GraphSPN's component-wise evaluator (`infer`):
    /// [`graphspn_compiler::instance::estimated_component_bytes`].
    Components {
        /// Decompositions kept.
        count: usize,
        /// Candidates drawn.
        candidates: usize,
        /// Classes of the model.
        classes: usize,
    },
    /// A tree mixture's exact evaluator (`infer`): per tree and place an upward and a
    /// downward message, a marginal row and the tree's links (measured: 290 bytes per
    /// place and tree with 10 classes, 1.9 GB for 64 trees at 100,000 places).
    Trees {
        /// Spanning trees.
        trees: usize,
        /// Classes of the model.
        classes: usize,
    },
    /// A tree mixture's explicit SPN and its text (`instance`): per tree and edge a
    /// C×C table of sums, per place C leaves; the text (JSON or dot) is the larger part
    /// (measured: 0.40 GB for 4 trees at 10,000 places, 7.9 GB at 100,000, with 10
    /// classes).
    TreeSpn {
        /// Spanning trees.
        trees: usize,
        /// Classes of the model.
        classes: usize,
    },
}

impl Work {
    /// The decompositions step of a GraphSPN command.
    pub fn decompositions(count: usize) -> Work {
        Work::Decompositions {
            count,
            candidates: candidates(count),
        }
    }

    /// Estimated bytes for a map of `places` places (the map itself included).
    pub fn bytes(self, places: usize) -> u128 {
        let n = places as u128;
        // The map (graph, places, names) and the command's fixed costs.
        let map = n * 600;
        map + match self {
            Work::Decompositions { count, candidates } => {
                n * (64 * count as u128 + 8 * candidates as u128)
            }
            Work::Components {
                count,
                candidates,
                classes,
            } => graphspn_compiler::instance::estimated_component_bytes(
                places, classes, count, candidates,
            ),
            Work::Trees { trees, classes } => {
                let (t, c) = (trees as u128, classes as u128);
                n * c * 8 * 3 + n * t * (c * 8 * 4 + 32)
            }
            Work::TreeSpn { trees, classes } => {
                let (t, c) = (trees as u128, classes as u128);
                n * t * c * c * 240
            }
        }
    }
}

/// Candidates drawn for `count` decompositions (the library's default).
pub fn candidates(count: usize) -> usize {
    (3 * count).max(15)
}

/// The work a command plans, the flag that sets its size, and any fixed place limit.
pub struct Budget {
    /// The flag and value that set the work's size, e.g. `--decompositions 5`.
    pub flag: String,
    /// What is built.
    pub work: Work,
    /// A limit on places that does not come from memory, and why (e.g. the generated
    /// code's 16-bit place indices).
    pub place_limit: Option<(usize, &'static str)>,
    /// What to do instead, when the work does not fit (default: lower the flag).
    pub advice: Option<&'static str>,
}

impl Budget {
    /// `work`, sized by `flag` (`--flag value`).
    pub fn new(flag: impl Into<String>, work: Work) -> Self {
        Budget {
            flag: flag.into(),
            work,
            place_limit: None,
            advice: None,
        }
    }

    /// With `advice` in the refusal instead of "lower the flag".
    pub fn advice(mut self, advice: &'static str) -> Self {
        self.advice = Some(advice);
        self
    }

    /// With a limit on places that does not come from memory.
    pub fn place_limit(mut self, limit: usize, why: &'static str) -> Self {
        self.place_limit = Some((limit, why));
        self
    }

    /// The largest map (places) the work fits for.
    pub fn max_places(&self) -> usize {
        // `bytes` grows with places: bisect.
        let (mut lo, mut hi) = (0usize, 1usize << 40);
        while lo < hi {
            let mid = lo + (hi - lo).div_ceil(2);
            if self.work.bytes(mid) <= MEMORY_LIMIT {
                lo = mid;
            } else {
                hi = mid - 1;
            }
        }
        match self.place_limit {
            Some((limit, _)) => lo.min(limit),
            None => lo,
        }
    }

    /// Refuses the work on a map of `places` places (`what`: the map, as the flag and
    /// path that named it) if it is over a fixed limit or its estimate is over
    /// [`MEMORY_LIMIT`].
    pub fn check(&self, what: &str, places: usize) -> Result<()> {
        if let Some((limit, why)) = self.place_limit
            && places > limit
        {
            bail!("{what}: {places} places; {why}");
        }
        let estimate = self.work.bytes(places);
        if estimate > MEMORY_LIMIT {
            bail!(
                "{what}: {places} places; {} on a map of that size would take about {} (limit {}): {}",
                self.flag,
                gb(estimate),
                gb(MEMORY_LIMIT),
                match self.advice {
                    Some(a) => a.to_string(),
                    None => format!(
                        "lower {} or use a smaller map",
                        self.flag.split_whitespace().next().unwrap_or("")
                    ),
                }
            );
        }
        Ok(())
    }
}

/// Reads the map at `resolved` (see [`super::map_input::declare_map`]) for `budget`: a map
/// with more places than the budget allows is refused while it is read, before its
/// graph is built. `flag` names the map in errors (`--map`).
pub fn read_map_within(flag: &str, resolved: &Path, budget: &Budget) -> Result<LoadedMap> {
    match read_map_limited(resolved, budget.max_places()) {
        Err(e) => match e.downcast_ref::<MapError>() {
            Some(MapError::TooManyPlaces { places, .. }) => {
                let what = format!("{flag} {}", resolved.display());
                budget.check(&what, *places)?;
                // Within the budget after all (cannot happen: the limit is the budget's).
                Err(e)
            }
            _ => Err(e),
        },
        Ok(m) => {
            budget.check(
                &format!("{flag} {}", resolved.display()),
                m.map.num_places(),
            )?;
            Ok(m)
        }
    }
}
