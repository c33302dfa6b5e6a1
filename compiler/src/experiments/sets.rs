//! The map sets of an evaluation (`graphspn evaluate`): the name each set is reported
//! under, its role and where it was read from.
//!
//! A set is named after its folder or file ([`crate::map::map_set_name`]) unless the
//! user names it (`--maps NAME=PATH`). Names must be distinct, since a run keys its
//! buildings by name; a user's folder may well be called like a training building
//! (a new set of Stockholm maps in a folder `Stockholm`), so [`name_sets`] gives a
//! set whose folder name is taken a distinct name instead of refusing it, and the
//! report says which set is which.

use serde::{Deserialize, Serialize};

/// Whether a map set is tested or trained on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SetRole {
    /// A test building (`--maps`): never read before testing.
    Test,
    /// A training building (`--train`, or a bundled COLD building by default).
    Training,
}

/// One map set of an evaluation.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MapSet {
    /// The name the set is reported under (tables, figures' file names, results.json).
    pub name: String,
    /// Tested or trained on.
    pub role: SetRole,
    /// Where it was read from (the path as given, or the bundled COLD folder).
    pub source: String,
    /// Whether it is one of the bundled COLD buildings (the default training sets).
    pub bundled: bool,
    /// Number of maps read.
    pub maps: usize,
    /// Why the set is not reported under its folder or file name, if it is not.
    pub note: Option<String>,
}

/// What an evaluation tested and trained on, recorded in results.json and REPORT.md.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Evaluation {
    /// The test sets, then the training sets, in the order given.
    pub sets: Vec<MapSet>,
}

impl Evaluation {
    /// The names of the sets with `role`, in order.
    pub fn names(&self, role: SetRole) -> Vec<&str> {
        self.sets
            .iter()
            .filter(|s| s.role == role)
            .map(|s| s.name.as_str())
            .collect()
    }
}

/// A set to be named: its role, the name the user gave (`NAME=PATH`), and its folder
/// or file name.
#[derive(Clone, Debug)]
pub struct NameRequest {
    /// Tested or trained on.
    pub role: SetRole,
    /// The name the user gave, if any: used as it is or refused.
    pub given: Option<String>,
    /// The folder or file name ([`crate::map::map_set_name`]).
    pub stem: String,
}

/// Checks a name the user gave a set: it becomes part of file names (`accuracy_NAME.svg`).
pub fn check_set_name(name: &str) -> Result<(), String> {
    if name.is_empty() {
        return Err("the name is empty".into());
    }
    if name.chars().count() > 100 {
        return Err("the name is longer than 100 characters".into());
    }
    if name.starts_with('.') {
        return Err("the name starts with '.' (it becomes part of file names)".into());
    }
    if let Some(c) = name.chars().find(|c| {
        c.is_control() || matches!(c, '/' | '\\' | ':' | '*' | '?' | '"' | '<' | '>' | '|')
    }) {
        return Err(format!(
            "the name holds {c:?} (it becomes part of file names; use letters, digits, '-', '_' or spaces)"
        ));
    }
    Ok(())
}

/// The name of every set of `requests`, in order, all distinct.
///
/// Given names are kept (two equal given names, or a given name equal to another
/// set's folder name that cannot move, are refused with a message saying what to do).
/// A set without a given name is named after its folder or file; when that name is
/// taken, a training set becomes `NAME-2`, `NAME-3`, … and a test set `NAME-test`,
/// `NAME-test-2`, … Training sets are named before test sets, so the training
/// buildings keep their names and a user's test folder called like one of them is
/// the one renamed. Returns, per set, its name and a note when it is not its folder
/// name.
pub fn name_sets(requests: &[NameRequest]) -> Result<Vec<(String, Option<String>)>, String> {
    let mut names: Vec<Option<(String, Option<String>)>> = vec![None; requests.len()];
    let mut taken: Vec<(String, usize)> = Vec::new();
    // Given names first: they are the user's explicit choice.
    for (i, r) in requests.iter().enumerate() {
        if let Some(g) = &r.given {
            check_set_name(g).map_err(|e| format!("{} name {g:?}: {e}", flag(r.role)))?;
            if let Some((_, j)) = taken.iter().find(|(n, _)| n == g) {
                return Err(format!(
                    "{} {g}=…: the name {g:?} is also given to another {} set; give each set its own NAME (NAME=PATH)",
                    flag(r.role),
                    flag(requests[*j].role)
                ));
            }
            taken.push((g.clone(), i));
            names[i] = Some((g.clone(), None));
        }
    }
    let order = requests
        .iter()
        .enumerate()
        .filter(|(_, r)| r.role == SetRole::Training)
        .chain(
            requests
                .iter()
                .enumerate()
                .filter(|(_, r)| r.role == SetRole::Test),
        );
    for (i, r) in order {
        if r.given.is_some() {
            continue;
        }
        let base = &r.stem;
        let holder = |n: &str| taken.iter().find(|(t, _)| t == n).map(|(_, j)| *j);
        let Some(first) = holder(base) else {
            taken.push((base.clone(), i));
            names[i] = Some((base.clone(), None));
            continue;
        };
        let candidate = |k: usize| match (r.role, k) {
            (SetRole::Test, 0) => format!("{base}-test"),
            (SetRole::Test, k) => format!("{base}-test-{}", k + 1),
            (SetRole::Training, k) => format!("{base}-{}", k + 2),
        };
        let name = (0..)
            .map(candidate)
            .find(|n| holder(n).is_none())
            .unwrap_or_else(|| format!("{base}-{i}"));
        let what = match requests[first].role {
            SetRole::Training => "training building",
            SetRole::Test => "test set",
        };
        let holder_name = names[first].as_ref().map_or(base.as_str(), |(n, _)| n);
        let note = format!(
            "its folder or file name {base:?} is also the name of {what} {holder_name:?}, so it is \
             reported as {name:?} ({} NAME=PATH chooses the name)",
            flag(r.role)
        );
        taken.push((name.clone(), i));
        names[i] = Some((name, Some(note)));
    }
    Ok(names.into_iter().map(|n| n.unwrap_or_default()).collect())
}

fn flag(role: SetRole) -> &'static str {
    match role {
        SetRole::Test => "--maps",
        SetRole::Training => "--train",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn req(role: SetRole, given: Option<&str>, stem: &str) -> NameRequest {
        NameRequest {
            role,
            given: given.map(str::to_string),
            stem: stem.into(),
        }
    }

    #[test]
    fn a_test_folder_called_like_a_training_building_is_renamed_not_refused() {
        let r = [
            req(SetRole::Test, None, "Stockholm"),
            req(SetRole::Training, None, "Freiburg"),
            req(SetRole::Training, None, "Stockholm"),
        ];
        let n = name_sets(&r).unwrap();
        assert_eq!(n[0].0, "Stockholm-test");
        assert!(n[0].1.as_deref().unwrap().contains("training building"));
        assert_eq!(n[1], ("Freiburg".into(), None));
        assert_eq!(n[2], ("Stockholm".into(), None));
    }

    #[test]
    fn equal_folder_names_get_distinct_names_and_given_names_win() {
        let r = [
            req(SetRole::Test, None, "site"),
            req(SetRole::Test, None, "site"),
            req(SetRole::Test, Some("site-test"), "x"),
            req(SetRole::Training, None, "a"),
            req(SetRole::Training, None, "a"),
        ];
        let n: Vec<String> = name_sets(&r).unwrap().into_iter().map(|x| x.0).collect();
        assert_eq!(n, ["site", "site-test-2", "site-test", "a", "a-2"]);
    }

    #[test]
    fn clashing_or_unusable_given_names_are_refused_with_what_to_do() {
        let r = [
            req(SetRole::Test, Some("x"), "a"),
            req(SetRole::Training, Some("x"), "b"),
        ];
        let e = name_sets(&r).unwrap_err();
        assert!(e.contains("\"x\"") && e.contains("NAME=PATH"), "{e}");
        let e = name_sets(&[req(SetRole::Test, Some("a/b"), "a")]).unwrap_err();
        assert!(e.contains("--maps") && e.contains("'/'"), "{e}");
        assert!(check_set_name("").is_err() && check_set_name(".x").is_err());
        assert!(check_set_name("Stockholm 2026").is_ok());
    }
}
