//! `graphspn reproduce`: the paper's experiments, REPORT.md, results.json and figures.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::Args;
use graphspn_compiler::decompose::DecompositionStrategy;
use graphspn_compiler::domain;
use graphspn_compiler::experiments::config::ReproduceConfig;
use graphspn_compiler::experiments::evidence::{NoiseLevel, WrongClassDraw};
use graphspn_compiler::experiments::grid::{ValidationGrid, ValidationSample};
use graphspn_compiler::experiments::protocol::training_buildings;
use graphspn_compiler::experiments::report::write_outputs;
use graphspn_compiler::experiments::reproduce::{load_data, run};
use graphspn_compiler::experiments::results::GivenSettings;
use graphspn_compiler::experiments::validate::{
    DecompositionChoice, ModelSettings, Validation, fold_buildings, validate_for,
};
use graphspn_compiler::experiments::validation_report::validation_markdown;
use graphspn_compiler::json_error::json_message;
use graphspn_compiler::learn::TrainingSettings;
use graphspn_compiler::mrf::Normalisation;
use std::collections::BTreeMap;

use super::flag_checks::{flag_domain, flag_error};
use super::map_input::{check_buildings, require_data_dir};
use super::output::{Outputs, write_folder};

/// Arguments of `graphspn reproduce`.
#[derive(Args)]
#[command(
    allow_negative_numbers = true,
    after_help = "Examples:
  graphspn reproduce --out out/
  graphspn reproduce --out out/ --quick
  graphspn reproduce --out out/ --levels 2,5 --rounds 1 --force"
)]
pub struct ReproduceArgs {
    /// Folder holding Freiburg/, Saarbrucken/, Stockholm/ (default: $GRAPHSPN_DATA, else the shipped data/cold-topomaps).
    #[arg(long)]
    data: Option<PathBuf>,
    #[command(flatten)]
    run: RunOptions,
    #[command(flatten)]
    protocol: ProtocolOptions,
    /// Reduced run: Stockholm only, 2 maps, NL2 and NL5, 1 round.
    #[arg(long)]
    quick: bool,
    /// Draw the wrong evidence class among all 10 classes (the paper's effective
    /// noise, reproducing its Table 1) instead of the 9 wrong ones.
    #[arg(long)]
    paper_noise: bool,
    /// Decompositions per instance of the validated GraphSPN (default: validation
    /// chooses between 5 of 15 and 20 of 60; the paper-style GraphSPN keeps 5 of 15).
    #[arg(long)]
    decompositions: Option<usize>,
    /// Candidate decompositions scored (default 15, or 3 × decompositions if larger).
    #[arg(long)]
    candidates: Option<usize>,
    /// Test buildings, comma-separated (default: all three).
    #[arg(long, value_delimiter = ',')]
    buildings: Option<Vec<String>>,
    /// Test maps per building.
    #[arg(long)]
    maps: Option<usize>,
    /// Use the settings of a saved validation (`graphspn validate --out DIR` writes
    /// DIR/validation.json) instead of running the validation again.
    #[arg(long)]
    settings: Option<PathBuf>,
    /// Training settings as JSON merged over every validated GraphSPN variant's, e.g. '{"em":"soft"}'.
    #[arg(long)]
    training: Option<String>,
    /// Paper-style MRF potentials from PMI ratios instead of joint frequencies.
    #[arg(long)]
    mrf_pmi: bool,
}

/// Arguments of `graphspn validate`.
#[derive(Args)]
#[command(after_help = "Examples:
  graphspn validate --out val/
  graphspn validate --out val/ --buildings Stockholm --tiny-grid
  graphspn reproduce --out out/ --settings val/validation.json")]
pub struct ValidateArgs {
    /// Folder holding Freiburg/, Saarbrucken/, Stockholm/ (default: $GRAPHSPN_DATA, else the shipped data/cold-topomaps).
    #[arg(long)]
    data: Option<PathBuf>,
    #[command(flatten)]
    run: RunOptions,
    /// Test buildings to validate for, comma-separated (default: all three).
    #[arg(long, value_delimiter = ',')]
    buildings: Option<Vec<String>>,
}

/// Output, seed and grid options shared by `reproduce`, `validate` and `evaluate`.
#[derive(Args)]
pub struct RunOptions {
    /// Output folder (reports, results and figures); created if missing, must be
    /// empty unless --force.
    #[arg(long)]
    pub out: PathBuf,
    /// Replace a non-empty --out folder (one graphspn wrote) as a whole.
    #[arg(long)]
    pub force: bool,
    /// Master seed of every random step.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Tiny validation grid (smoke runs).
    #[arg(long)]
    pub tiny_grid: bool,
}

impl RunOptions {
    /// The protocol configuration to start from (`quick`: the reduced run) with the
    /// seed and grid these options ask for.
    pub fn config(&self, quick: bool) -> ReproduceConfig {
        let mut cfg = if quick {
            ReproduceConfig::quick(self.seed)
        } else {
            ReproduceConfig::full(self.seed)
        };
        if self.tiny_grid {
            cfg.grid = ValidationGrid::tiny();
        }
        cfg
    }
}

/// Test-protocol options shared by `reproduce` and `evaluate`.
#[derive(Args)]
pub struct ProtocolOptions {
    /// Noise levels to run, comma-separated (default: 1..6).
    #[arg(long, value_delimiter = ',')]
    pub levels: Option<Vec<u8>>,
    /// Evidence rounds per map and level (default 3; `reproduce --quick` uses 1).
    #[arg(long)]
    pub rounds: Option<usize>,
    /// Skip the novelty-detection experiment.
    #[arg(long)]
    pub no_novelty: bool,
}

impl ProtocolOptions {
    /// Checks the options and applies them to `cfg`.
    pub fn apply(&self, cfg: &mut ReproduceConfig) -> Result<()> {
        if let Some(l) = &self.levels {
            if l.is_empty() {
                bail!("--levels: give at least one noise level");
            }
            cfg.levels = l
                .iter()
                .map(|&x| NoiseLevel::new(x).with_context(|| format!("--levels {x}")))
                .collect::<Result<_, _>>()?;
        }
        if let Some(r) = self.rounds {
            flag_domain("--rounds", domain::rounds("rounds", r))?;
            cfg.rounds = r;
        }
        if self.no_novelty {
            cfg.novelty = false;
        }
        Ok(())
    }
}

/// Runs `graphspn validate`: the leave-one-training-building-out search of every
/// model's settings, per test building; writes validation.json and VALIDATION.md.
pub fn validate_cmd(args: ValidateArgs) -> Result<()> {
    // Every argument and the output folder are checked before any computation.
    let data = require_data_dir(args.data)?;
    let mut outputs = Outputs::new(args.run.force);
    outputs.input("--data", &data);
    outputs.folder("--out", &args.run.out)?;
    let cfg = args.run.config(false);
    let buildings = args.buildings.unwrap_or(cfg.test_buildings.clone());
    check_buildings("--buildings", &buildings)?;
    let start = Instant::now();
    let all = load_data(&data)?;
    let mut vals = Vec::new();
    for b in &buildings {
        eprintln!("validating the settings for test building {b} (on the other two buildings)");
        let v = validate_for(&all, b, &cfg)?;
        let secs: Vec<String> = v
            .seconds
            .iter()
            .map(|(m, t)| format!("{m} {t:.1} s"))
            .collect();
        eprintln!("  searched in {}", secs.join(", "));
        vals.push(v);
    }
    let settings: BTreeMap<String, ModelSettings> = vals
        .iter()
        .map(|v| (v.test_building.clone(), v.chosen.clone()))
        .collect();
    let json = serde_json::json!({
        "settings": settings,
        "sample": cfg.grid.sample(),
        "validation": vals,
    });
    let md = validation_markdown(&vals, &cfg.grid, start.elapsed().as_secs_f64());
    write_folder(&args.run.out, |dir| {
        std::fs::write(
            dir.join("validation.json"),
            serde_json::to_string_pretty(&json)?,
        )?;
        std::fs::write(dir.join("VALIDATION.md"), &md)?;
        Ok(())
    })?;
    eprintln!(
        "validation done in {:.1} s; wrote {}",
        start.elapsed().as_secs_f64(),
        args.run.out.join("VALIDATION.md").display()
    );
    Ok(())
}

/// A validation.json as `--settings` reads it: the chosen settings per test building
/// and the validation that chose them (only its folds are read).
#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct SettingsFile {
    settings: BTreeMap<String, ModelSettings>,
    /// What the validation scored candidates on (absent in files written before it
    /// was recorded).
    #[serde(default)]
    sample: Option<ValidationSample>,
    /// The validation records: their folds are read, and each whole record is kept
    /// for the report when it parses.
    #[serde(default)]
    validation: Vec<serde_json::Value>,
}

/// One test building's validation in a validation.json: its folds name the training
/// buildings (`A+B → C`: trained on A and B, validated on C).
#[derive(serde::Deserialize)]
struct ValidationRecord {
    test_building: String,
    folds: Vec<String>,
}

/// The settings of a validation.json (`--settings`), per test building, with the
/// training buildings each was validated on where the file records them.
pub struct SavedSettings {
    /// The file, for messages.
    path: PathBuf,
    /// The chosen settings per test building.
    pub settings: BTreeMap<String, ModelSettings>,
    /// The buildings each test building's validation trained and validated on.
    validated_on: BTreeMap<String, std::collections::BTreeSet<String>>,
    /// What the validation scored candidates on, when the file records it.
    sample: Option<ValidationSample>,
    /// The file's whole validation records (those that parse).
    validations: Vec<Validation>,
}

impl SavedSettings {
    /// Where a run's settings came from, for its report: this file, the `entry` used
    /// for every test set (`evaluate --settings-of`) or none (`reproduce`: each test
    /// building its own), and the validation records of `used` test buildings.
    pub fn given(&self, used: &[String], entry: Option<String>) -> GivenSettings {
        GivenSettings {
            file: self.path.display().to_string(),
            entry,
            sample: self.sample.clone(),
            validation: self
                .validations
                .iter()
                .filter(|v| used.contains(&v.test_building))
                .cloned()
                .collect(),
        }
    }

    /// Refuses a run of `test_building` the file has no settings for, or whose settings
    /// were validated on other buildings than `training` (the models would be trained
    /// on one set and tuned on another). Files without the validation's folds are
    /// taken as they are.
    pub fn check_training(&self, test_building: &str, training: &[String]) -> Result<()> {
        if !self.settings.contains_key(test_building) {
            bail!(
                "--settings {}: holds no settings for test building {test_building} (it has {}); validate that building, or choose others with --buildings",
                self.path.display(),
                self.settings.keys().cloned().collect::<Vec<_>>().join(", ")
            );
        }
        let Some(validated) = self.validated_on.get(test_building) else {
            return Ok(());
        };
        let training: std::collections::BTreeSet<String> = training.iter().cloned().collect();
        if *validated != training {
            let list = |s: &std::collections::BTreeSet<String>| {
                s.iter().cloned().collect::<Vec<_>>().join(", ")
            };
            bail!(
                "--settings {}: the settings of {test_building} were validated on {}, but this run trains on {}; use a validation on the same training buildings (graphspn validate; NAME=PATH names a --train set), or leave out --settings to validate here",
                self.path.display(),
                list(validated),
                list(&training)
            );
        }
        Ok(())
    }
}

/// Reads the per-building settings of a validation.json: unknown fields are errors,
/// and every building's settings are checked against their domains
/// ([`ModelSettings::check`]) before any work.
/// Errors start with `--settings PATH`.
pub fn read_settings(path: &std::path::Path) -> Result<SavedSettings> {
    let at = format!("--settings {}", path.display());
    let text = std::fs::read_to_string(path).with_context(|| at.clone())?;
    let file: SettingsFile = serde_json::from_str(&text).map_err(|e| {
        anyhow::anyhow!(
            "{at}:{}:{}: not a settings file (graphspn validate writes validation.json): {}",
            e.line(),
            e.column(),
            json_message(&e)
        )
    })?;
    for (building, s) in &file.settings {
        s.check().map_err(|e| {
            let path: Vec<&str> = ["settings", building.as_str()]
                .into_iter()
                .chain(e.setting.split('.'))
                .collect();
            let line = key_line(&text, &path).map_or(String::new(), |l| format!(":{l}"));
            anyhow::anyhow!("{at}{line}: settings of {building}: {e}")
        })?;
    }
    let mut validated_on = BTreeMap::new();
    let mut validations = Vec::new();
    for (i, value) in file.validation.iter().enumerate() {
        let v: ValidationRecord = serde_json::from_value(value.clone())
            .map_err(|e| anyhow::anyhow!("{at}: validation record {i}: not a validation ({e})"))?;
        if let Ok(whole) = serde_json::from_value::<Validation>(value.clone()) {
            validations.push(whole);
        }
        let mut buildings = std::collections::BTreeSet::new();
        for fold in &v.folds {
            let Some((train, val)) = fold_buildings(fold) else {
                bail!(
                    "{at}: validation of {}: fold {fold:?} is not TRAIN → VALIDATE",
                    v.test_building
                );
            };
            buildings.extend(train.into_iter().map(str::to_string));
            buildings.insert(val.to_string());
        }
        validated_on.insert(v.test_building.clone(), buildings);
    }
    Ok(SavedSettings {
        path: path.to_path_buf(),
        settings: file.settings,
        validated_on,
        sample: file.sample,
        validations,
    })
}

/// The line of the value at `path` (object keys, outermost first) in the JSON `text`,
/// found by looking for each key after the previous one (each nested object follows
/// its key); `None` if a key is not there (a value taken by default).
fn key_line(text: &str, path: &[&str]) -> Option<usize> {
    let mut at = 0;
    for key in path {
        let quoted = serde_json::to_string(key).ok()?;
        let mut from = at;
        at = loop {
            let i = from + text[from..].find(&quoted)?;
            let after = text[i + quoted.len()..].trim_start();
            if after.starts_with(':') {
                break i + quoted.len();
            }
            from = i + quoted.len();
        };
    }
    Some(text[..at].matches('\n').count() + 1)
}

/// Merges `patch` into `base`: objects key by key, at every depth (so
/// `{"structure": {"sums": 3}}` changes one field of the structure and keeps the
/// variant's others); anything else replaces what it overrides.
fn merge_json(base: &mut serde_json::Value, patch: serde_json::Value) {
    match (base, patch) {
        (serde_json::Value::Object(b), serde_json::Value::Object(p)) => {
            for (k, x) in p {
                match b.get_mut(&k) {
                    Some(old) => merge_json(old, x),
                    None => {
                        b.insert(k, x);
                    }
                }
            }
        }
        (b, x) => *b = x,
    }
}

/// Runs `graphspn reproduce`.
pub fn run_cmd(args: ReproduceArgs) -> Result<()> {
    // Every argument and the output folder are checked before any computation.
    let data = require_data_dir(args.data)?;
    let mut outputs = Outputs::new(args.run.force);
    outputs.input("--data", &data);
    if let Some(p) = &args.settings {
        outputs.input_file("--settings", p)?;
    }
    outputs.folder("--out", &args.run.out)?;
    let mut cfg = args.run.config(args.quick);
    if args.paper_noise {
        cfg.wrong_draw = WrongClassDraw::AnyClass;
    }
    if args.decompositions.is_some() || args.candidates.is_some() {
        let d = args.decompositions.unwrap_or(5);
        let cands = args.candidates.unwrap_or((3 * d).max(15));
        // Both strategies with this D; validation picks one.
        cfg.grid.graphspn_decompositions = DecompositionStrategy::ALL
            .iter()
            .map(|&s| DecompositionChoice::new(s, d, cands))
            .collect();
        DecompositionChoice::new(DecompositionStrategy::Paper, d, cands)
            .check()
            .map_err(|e| {
                flag_error(
                    e,
                    &[
                        ("count", "--decompositions"),
                        ("candidates", "--candidates"),
                    ],
                )
            })?;
    }
    if let Some(b) = args.buildings {
        check_buildings("--buildings", &b)?;
        cfg.test_buildings = b;
    }
    args.protocol.apply(&mut cfg)?;
    if let Some(m) = args.maps {
        flag_domain("--maps", domain::maps("maps_per_building", m))?;
        cfg.maps_per_building = m;
    }
    let saved = args.settings.as_deref().map(read_settings).transpose()?;
    if let Some(t) = &args.training {
        if args.settings.is_some() {
            bail!(
                "--training: not used with --settings (the saved settings are used as they are); give one or the other"
            );
        }
        let patch: serde_json::Value = serde_json::from_str(t).context("--training JSON")?;
        let Some(p) = patch.as_object() else {
            bail!("--training {t}: give a JSON object, e.g. '{{\"em\":\"soft\"}}'");
        };
        // Keys the run sets itself would be silently replaced: refused.
        for (key, why) in [
            ("seed", "every training seed is derived from --seed"),
            (
                "temperature",
                "the template temperature is searched by the validation",
            ),
        ] {
            if p.contains_key(key) {
                bail!("--training: {key} cannot be set here ({why})");
            }
        }
        if p.get("structure")
            .and_then(|s| s.get("split_choice"))
            .is_some()
        {
            bail!(
                "--training: structure.split_choice cannot be set here (the validation searches both Star structures, and the report names each variant by it)"
            );
        }
        for (_, settings) in cfg.grid.graphspn_variants.iter_mut() {
            let mut v = settings.to_value();
            merge_json(&mut v, patch.clone());
            *settings = TrainingSettings::from_value(&v).context("--training settings")?;
            settings
                .check()
                .map_err(|e| anyhow::anyhow!("--training: {e}"))?;
        }
    }
    if args.mrf_pmi {
        cfg.cooccurrence.normalisation = Normalisation::Pmi;
    }
    let start = Instant::now();
    let all = load_data(&data)?;
    if let Some(saved) = &saved {
        for b in &cfg.test_buildings {
            let training = training_buildings(&all, b, &cfg)?;
            saved.check_training(b, &training)?;
        }
        cfg.settings = Some(saved.settings.clone());
    }
    let (mut rep, setups) = run(&all, &cfg)?;
    rep.seconds = start.elapsed().as_secs_f64();
    rep.given_settings = saved.map(|s| s.given(&cfg.test_buildings, None));
    let check =
        super::generated_check::section(args.run.seed, if args.quick { 1 } else { cfg.rounds })?;
    write_folder(&args.run.out, |dir| {
        Ok(write_outputs(&rep, &setups, &cfg, dir, &check)?)
    })?;
    eprintln!(
        "reproduction done in {:.1} s; wrote {}",
        start.elapsed().as_secs_f64(),
        args.run.out.join("REPORT.md").display()
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::merge_json;
    use serde_json::json;

    /// `--training` changes the fields it names, at every depth, and keeps the rest of
    /// each variant (a structure override used to replace the whole structure, and
    /// with it the variant's Star split).
    #[test]
    fn a_training_patch_merges_field_by_field() {
        let mut v =
            json!({"structure": {"sums": 2, "split_choice": "fewest_images"}, "em": "hard"});
        merge_json(&mut v, json!({"structure": {"sums": 3}, "epochs": 4}));
        assert_eq!(
            v,
            json!({"structure": {"sums": 3, "split_choice": "fewest_images"}, "em": "hard", "epochs": 4})
        );
    }
}
