//! What a run of the experiments does ([`ReproduceConfig`]: test and training
//! buildings, maps, rounds, noise levels, the paper-style models, the validation grid
//! or settings chosen beforehand), and the check of every setting it holds against
//! its domain before any work ([`check_settings`]).

use std::collections::BTreeMap;

use super::error::ReproduceError;
use super::evidence::{NoiseLevel, WrongClassDraw};
use super::grid::ValidationGrid;
use super::settings::{GraphSpnSetting, ModelSettings};
use crate::learn::Progress;
use crate::map::cold;
use crate::mrf::{BpOptions, CooccurrenceParams};

/// What to run. [`ReproduceConfig::full`] is the paper's protocol,
/// [`ReproduceConfig::quick`] a reduced smoke run.
#[derive(Clone, Debug)]
pub struct ReproduceConfig {
    /// Master seed.
    pub seed: u64,
    /// Test buildings (each is tested with a model trained on the other buildings,
    /// or on `train_buildings`).
    pub test_buildings: Vec<String>,
    /// Buildings every model is trained (and validated) on; `None`: for each test
    /// building, all the other buildings (the paper's protocol).
    pub train_buildings: Option<Vec<String>>,
    /// Test maps per building (paper: 5), chosen at random (seeded).
    pub maps_per_building: usize,
    /// Evidence rounds per map and level (paper: 3).
    pub rounds: usize,
    /// Noise levels.
    pub levels: Vec<NoiseLevel>,
    /// Settings of the paper-style GraphSPN ("GraphSPN paper"; the seed of its
    /// training is replaced per building).
    pub graphspn_paper: GraphSpnSetting,
    /// Potentials of the paper-style MRFs (raw joint frequencies by default).
    pub cooccurrence: CooccurrenceParams,
    /// Loopy BP options of the paper-style MRFs.
    pub bp: BpOptions,
    /// The validation search that picks every model's settings on the training
    /// buildings of each test building (ignored when `settings` is given).
    pub grid: ValidationGrid,
    /// Settings chosen beforehand (e.g. a saved validation), one per test
    /// building; `None` runs the validation.
    pub settings: Option<BTreeMap<String, ModelSettings>>,
    /// How wrong evidence classes are drawn (protocol as written, or the paper's effective noise).
    pub wrong_draw: WrongClassDraw,
    /// Run the novelty-detection experiment.
    pub novelty: bool,
    /// Progress bars.
    pub progress: Progress,
}

impl ReproduceConfig {
    /// The paper's protocol on every map of each test building (the paper used
    /// 5): 3 buildings, 3 rounds, NL1..6, D = 5 of 15, validated settings.
    pub fn full(seed: u64) -> Self {
        ReproduceConfig {
            seed,
            test_buildings: cold::BUILDINGS.iter().map(|s| s.to_string()).collect(),
            train_buildings: None,
            maps_per_building: usize::MAX,
            rounds: 3,
            levels: NoiseLevel::all().to_vec(),
            graphspn_paper: GraphSpnSetting::paper(),
            cooccurrence: CooccurrenceParams::default(),
            bp: BpOptions {
                max_iterations: 200,
                ..BpOptions::default()
            },
            wrong_draw: WrongClassDraw::Others,
            novelty: true,
            grid: ValidationGrid::standard(),
            settings: None,
            progress: Progress::Auto,
        }
    }

    /// A reduced run: 1 building (Stockholm), 2 maps, NL2 and NL5, 1 round,
    /// a tiny validation grid.
    pub fn quick(seed: u64) -> Self {
        let lv = |l| NoiseLevel::new(l).expect("levels 2 and 5 exist");
        ReproduceConfig {
            test_buildings: vec!["Stockholm".into()],
            maps_per_building: 2,
            rounds: 1,
            levels: vec![lv(2), lv(5)],
            bp: BpOptions {
                max_iterations: 200,
                ..BpOptions::default()
            },
            grid: ValidationGrid::tiny(),
            ..ReproduceConfig::full(seed)
        }
    }
}

/// Every setting `cfg` holds against its documented domain ([`crate::domain`]), before
/// any work: the rounds and maps per building, the settings given per test building,
/// the paper-style models' and every candidate of the validation grid.
pub fn check_settings(cfg: &ReproduceConfig) -> Result<(), ReproduceError> {
    let bad =
        |what: &str, e: crate::domain::DomainError| ReproduceError::Config(format!("{what}: {e}"));
    crate::domain::rounds("rounds", cfg.rounds).map_err(|e| bad("protocol", e))?;
    crate::domain::maps("maps_per_building", cfg.maps_per_building)
        .map_err(|e| bad("protocol", e))?;
    if let Some(given) = &cfg.settings {
        for (b, s) in given {
            s.check()
                .map_err(|e| bad(&format!("settings of test building {b}"), e))?;
        }
    }
    cfg.graphspn_paper
        .check()
        .map_err(|e| bad("paper-style GraphSPN", e))?;
    cfg.cooccurrence
        .check()
        .map_err(|e| bad("paper-style MRF potentials", e))?;
    cfg.bp.check().map_err(|e| bad("paper-style MRF BP", e))?;
    cfg.grid.check().map_err(|e| bad("validation grid", e))
}
