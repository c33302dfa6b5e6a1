//! The one output policy of every sub-command.
//!
//! A command first declares its inputs ([`Outputs::input`]) and its outputs
//! ([`Outputs::file`], [`Outputs::folder`]); every check runs there, before any
//! computation or write:
//!
//! - an output may never be one of the command's inputs (nor lie inside an input
//!   folder when it exists), `--force` or not;
//! - an existing output file is replaced only with `--force`; a non-empty output
//!   folder is written into only with `--force`;
//! - the folder an output file goes into must exist, and two outputs may not be the
//!   same file.
//!
//! Files are then written atomically ([`write_files`]): each to a temporary file in
//! its destination folder, renamed over the destination only once every temporary
//! file of the command is complete. A failure leaves no output created or changed.

use std::io::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};

/// An input of the command: a file or a folder, with the flag that named it.
struct Input {
    flag: String,
    shown: PathBuf,
    canonical: PathBuf,
    is_dir: bool,
}

/// The inputs and planned outputs of one command run, and whether `--force` was given.
pub struct Outputs {
    force: bool,
    inputs: Vec<Input>,
    planned: Vec<(String, PathBuf)>,
}

/// Absolute form of `path` with symbolic links resolved, also for a path that does
/// not exist yet (its parent folder is resolved instead).
fn resolve(path: &Path) -> Option<PathBuf> {
    if let Ok(c) = std::fs::canonicalize(path) {
        return Some(c);
    }
    let name = path.file_name()?;
    let parent = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    Some(std::fs::canonicalize(parent).ok()?.join(name))
}

impl Outputs {
    /// No inputs or outputs yet; `force` is the command's `--force`.
    pub fn new(force: bool) -> Self {
        Outputs {
            force,
            inputs: Vec::new(),
            planned: Vec::new(),
        }
    }

    /// Declares an input (a file or folder that exists; others are ignored here:
    /// reading them will fail with its own error).
    pub fn input(&mut self, flag: &str, path: &Path) {
        if let Ok(canonical) = std::fs::canonicalize(path) {
            self.inputs.push(Input {
                flag: flag.to_string(),
                shown: path.to_path_buf(),
                is_dir: canonical.is_dir(),
                canonical,
            });
        }
    }

    /// The input an output at `target` (resolved) would replace or write into.
    fn clashing_input(&self, target: &Path, exists: bool) -> Option<&Input> {
        self.inputs.iter().find(|i| {
            target == i.canonical
                || (i.is_dir && exists && target.starts_with(&i.canonical))
                || (target.is_dir() && i.canonical.starts_with(target))
        })
    }

    /// Declares an output file named by `flag`; fails (writing nothing) if it cannot
    /// or may not be written. See the module documentation.
    pub fn file(&mut self, flag: &str, path: &Path) -> Result<()> {
        self.file_replacing(flag, path, false)
    }

    /// [`Outputs::file`], where `replace_ok` also allows replacing an existing file
    /// without `--force` (e.g. one the command itself generated, or one whose content
    /// would not change).
    pub fn file_replacing(&mut self, flag: &str, path: &Path, replace_ok: bool) -> Result<()> {
        let shown = path.display();
        if path.as_os_str().is_empty() {
            bail!("{flag}: empty file name");
        }
        if path.is_dir() {
            bail!("{flag} {shown}: is a folder (give a file name)");
        }
        let parent = match path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => Path::new("."),
        };
        if !parent.is_dir() {
            bail!("{flag} {shown}: folder {} does not exist", parent.display());
        }
        let target = resolve(path).with_context(|| format!("{flag} {shown}: not a file name"))?;
        let exists = path.exists();
        if let Some(i) = self.clashing_input(&target, exists) {
            bail!(
                "{flag} {shown}: would replace the input {} {} of this command; choose another file",
                i.flag,
                i.shown.display()
            );
        }
        if let Some((other, _)) = self.planned.iter().find(|(_, p)| *p == target) {
            bail!("{flag} {shown}: is also the output of {other}");
        }
        if exists && !self.force && !replace_ok {
            bail!("{flag} {shown}: exists; pass --force to replace it");
        }
        self.planned.push((flag.to_string(), target));
        Ok(())
    }

    /// Declares an output folder named by `flag`: it may be missing (it is created
    /// when writing) or empty; a non-empty folder needs `--force`; a file is refused.
    pub fn folder(&mut self, flag: &str, path: &Path) -> Result<()> {
        let shown = path.display();
        if path.as_os_str().is_empty() {
            bail!("{flag}: empty folder name");
        }
        if path.exists() && !path.is_dir() {
            bail!("{flag} {shown}: exists and is not a folder");
        }
        if path.is_dir() {
            let non_empty = std::fs::read_dir(path)
                .with_context(|| format!("{flag} {shown}: cannot list the folder"))?
                .next()
                .is_some();
            if non_empty && !self.force {
                bail!("{flag} {shown}: folder is not empty; pass --force to write into it");
            }
        }
        if let Some(target) = resolve(path)
            && let Some(i) = self.inputs.iter().find(|i| {
                target == i.canonical
                    || target.starts_with(&i.canonical)
                    || i.canonical.starts_with(&target)
            })
        {
            bail!(
                "{flag} {shown}: overlaps the input {} {} of this command; choose another folder",
                i.flag,
                i.shown.display()
            );
        }
        Ok(())
    }
}

/// Writes every `(path, content)` atomically: all temporary files (in each
/// destination's folder) first, then one rename each. Permissions of a replaced
/// file are kept; new files get the usual `rw-r--r--`.
pub fn write_files(files: &[(&Path, &[u8])]) -> Result<()> {
    let mut temps = Vec::with_capacity(files.len());
    for &(path, bytes) in files {
        let dir = match path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => Path::new("."),
        };
        let mut tmp = tempfile::Builder::new()
            .prefix(".graphspn-")
            .tempfile_in(dir)
            .with_context(|| format!("creating a temporary file in {}", dir.display()))?;
        tmp.write_all(bytes)
            .and_then(|()| tmp.flush())
            .with_context(|| format!("writing {}", path.display()))?;
        let perms = match std::fs::metadata(path) {
            Ok(m) => m.permissions(),
            Err(_) => default_permissions(tmp.as_file())?,
        };
        std::fs::set_permissions(tmp.path(), perms)
            .with_context(|| format!("setting the permissions of {}", path.display()))?;
        temps.push((tmp, path));
    }
    for (tmp, path) in temps {
        tmp.persist(path)
            .with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}

#[cfg(unix)]
fn default_permissions(f: &std::fs::File) -> Result<std::fs::Permissions> {
    use std::os::unix::fs::PermissionsExt as _;
    let mut p = f.metadata()?.permissions();
    p.set_mode(0o644);
    Ok(p)
}

#[cfg(not(unix))]
fn default_permissions(f: &std::fs::File) -> Result<std::fs::Permissions> {
    Ok(f.metadata()?.permissions())
}

/// Output of a command: a file (written atomically) or, when `None`, standard output.
pub fn emit(path: Option<&Path>, text: &str) -> Result<()> {
    match path {
        Some(p) => write_files(&[(p, text.as_bytes())]),
        None => super::common::write_stdout(text),
    }
}

/// Writes a set of files made by `make` into the folder `out`: `make` writes into a
/// fresh temporary folder next to `out`, whose files are then moved into `out`
/// (created if missing) one rename each. Nothing reaches `out` if `make` fails.
pub fn write_folder(out: &Path, make: impl FnOnce(&Path) -> Result<()>) -> Result<PathBuf> {
    // The nearest existing ancestor holds the temporary folder (same file system).
    let mut base = out.to_path_buf();
    while !base.is_dir() {
        match base.parent() {
            Some(p) if !p.as_os_str().is_empty() => base = p.to_path_buf(),
            _ => {
                base = PathBuf::from(".");
                break;
            }
        }
    }
    let tmp = tempfile::Builder::new()
        .prefix(".graphspn-")
        .tempdir_in(&base)
        .with_context(|| format!("creating a temporary folder in {}", base.display()))?;
    make(tmp.path())?;
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let mut names: Vec<_> = std::fs::read_dir(tmp.path())?
        .map(|e| e.map(|e| e.file_name()))
        .collect::<Result<_, _>>()?;
    names.sort();
    for name in names {
        let to = out.join(&name);
        std::fs::rename(tmp.path().join(&name), &to)
            .with_context(|| format!("writing {}", to.display()))?;
    }
    Ok(out.to_path_buf())
}
