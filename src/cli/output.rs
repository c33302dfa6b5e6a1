//! The one output policy of every sub-command.
//!
//! A command first declares its inputs ([`Outputs::input`]) and its outputs
//! ([`Outputs::file`], [`Outputs::folder`]); every check runs there, before any
//! computation or write:
//!
//! - an output may never be one of the command's inputs (nor lie inside an input
//!   folder when it exists), `--force` or not;
//! - whatever exists at an output's path is replaced only with `--force`: a file, a
//!   symbolic link (a dangling one too: the link is replaced, never its target) or a
//!   non-empty folder; and `--force` replaces a non-empty folder only if graphspn
//!   wrote it (it holds the [`MARKER`] file every output folder gets), as a whole;
//! - the folder an output file goes into must exist (an output folder's missing
//!   parent folders are created), and two outputs may not be the same file;
//! - the folder the output goes into must be writable: declaring the output creates
//!   its lock file there, and fails, naming the output, if it cannot;
//! - one run at a time per output: the declaration takes an exclusive lock on the
//!   output (the lock file below, `flock` on Unix) held until the command ends, so a
//!   second run writing the same output at the same time stops at once with
//!   "another graphspn run (process N) is writing it".
//!
//! # Names next to an output
//!
//! For an output `DIR/NAME`, graphspn uses these hidden names in `DIR`:
//!
//! - `.NAME.graphspn-lock`: the lock file, removed when the run ends (a killed run
//!   leaves it unlocked; the next run writing `NAME` takes it over and removes it);
//! - `.NAME.graphspn-tmp-XXXXXX`: the new file or folder while it is written, and,
//!   after the swap, the previous folder while it is deleted;
//! - `.NAME.graphspn-old-XXXXXX`: the previous folder during a swap by two renames
//!   (only where the file system cannot exchange two names in one step).
//!
//! Once a run holds the lock of `NAME`, every other such name is stale, left by a
//! killed run: the run removes it right after taking the lock, except an `-old-`
//! folder with nothing at `NAME`, which it renames back to `NAME` (that is the
//! previous output, interrupted between the two renames).
//!
//! # What a crash leaves
//!
//! An output file is written to a temporary file beside it (flushed to disk), then
//! renamed over the destination in one step: a `kill -9` at any instant leaves the
//! previous file or the complete new one. A command writing several files renames
//! them one after the other once all are complete, so a crash between two renames
//! leaves some files new and the others previous, each complete.
//!
//! An output folder is built complete (with its [`MARKER`]) under
//! `.NAME.graphspn-tmp-XXXXXX`, then put in place by one rename (no previous folder)
//! or, on Linux, one `renameat2(RENAME_EXCHANGE)` that swaps it with the previous
//! folder, which is then deleted. A crash before the rename or exchange leaves the
//! previous output (and a stale temporary folder); after it, the complete new one
//! (and the previous one under the temporary name until the next run removes it).
//! Where the exchange is not supported the swap takes two renames (`NAME` to
//! `.NAME.graphspn-old-XXXXXX`, then the new folder to `NAME`); a crash between them
//! leaves nothing at `NAME` until the next run renames the previous folder back.

use std::fs::{File, OpenOptions};
use std::io::{Read as _, Write as _};
use std::path::{Component, Path, PathBuf};

use anyhow::{Context, Result, bail};

/// The file every output folder holds: it marks the folder as graphspn's own, which
/// `--force` may replace as a whole.
pub const MARKER: &str = ".graphspn-output";

/// Content of [`MARKER`].
const MARKER_TEXT: &str =
    "This folder was written by graphspn, which replaces it as a whole when given --force.\n";

/// An input of the command: a file or a folder, with the flag that named it.
struct Input {
    flag: String,
    shown: PathBuf,
    canonical: PathBuf,
    is_dir: bool,
}

/// The inputs and planned outputs of one command run, and whether `--force` was given.
/// Holds the lock of every declared output until it is dropped (the end of the run).
pub struct Outputs {
    force: bool,
    inputs: Vec<Input>,
    planned: Vec<(String, PathBuf)>,
    locks: Vec<Lock>,
}

/// Absolute form of `path` with symbolic links resolved, also for a path that does
/// not exist yet (its parent folder is resolved instead).
fn resolve(path: &Path) -> Option<PathBuf> {
    if let Ok(c) = std::fs::canonicalize(path) {
        return Some(c);
    }
    entry(path)
}

/// The folder `path` is an entry of (`.` for a bare name).
fn parent_of(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// Absolute form of the entry `path` names: its parent folder resolved (as far as it
/// exists), its own name kept (a symbolic link at `path` is not followed).
fn entry(path: &Path) -> Option<PathBuf> {
    let name = path.file_name()?;
    Some(resolve_folder(parent_of(path))?.join(name))
}

/// Absolute form of the folder `dir` with the symbolic links of the part that exists
/// resolved; the missing rest is appended as written (`..` taken lexically: it holds
/// no link).
fn resolve_folder(dir: &Path) -> Option<PathBuf> {
    if let Ok(c) = std::fs::canonicalize(dir) {
        return Some(c);
    }
    let mut out = PathBuf::new();
    let mut exists = true;
    for c in std::path::absolute(dir).ok()?.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                out.pop();
            }
            other => {
                out.push(other);
                if exists {
                    match std::fs::canonicalize(&out) {
                        Ok(c) => out = c,
                        Err(_) => exists = false,
                    }
                }
            }
        }
    }
    Some(out)
}

/// `DIR/.NAME.graphspn-KIND` for the output `DIR/NAME`.
fn sibling(dest: &Path, kind: &str) -> PathBuf {
    let name = dest.file_name().unwrap_or_default().to_string_lossy();
    parent_of(dest).join(format!(".{name}.graphspn-{kind}"))
}

/// The one check of every input file's path (`--model`, `--evidence`, …): a folder
/// or a missing path is refused with the flag and the path.
pub fn check_input_file(flag: &str, path: &Path) -> Result<()> {
    if path.is_dir() {
        bail!("{flag} {}: is a folder, not a file", path.display());
    }
    if !path.exists() {
        bail!("{flag} {}: no such file", path.display());
    }
    Ok(())
}

/// What `path` is when it exists (following links) and is neither a file nor a
/// folder: `"a character device"`, `"a named pipe"`, …; `None` otherwise.
fn special_file(path: &Path) -> Option<&'static str> {
    let m = std::fs::metadata(path).ok()?;
    if m.is_file() || m.is_dir() {
        return None;
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        let t = m.file_type();
        for (is, kind) in [
            (t.is_char_device(), "a character device"),
            (t.is_block_device(), "a block device"),
            (t.is_fifo(), "a named pipe"),
            (t.is_socket(), "a socket"),
        ] {
            if is {
                return Some(kind);
            }
        }
    }
    Some("a special file")
}

/// What a symbolic link at `path` points to, for messages.
fn link_target(path: &Path) -> String {
    std::fs::read_link(path).map_or_else(|_| "?".into(), |t| t.display().to_string())
}

/// The exclusive claim of one run on one output: the open, locked lock file.
struct Lock {
    path: PathBuf,
    _file: File,
}

impl Drop for Lock {
    fn drop(&mut self) {
        // Removed while still locked (the file closes after this), so a run that
        // opened it meanwhile finds its lock on a removed file and opens a new one.
        let _ = std::fs::remove_file(&self.path);
    }
}

/// Whether the open `file` is still the file at `path`.
#[cfg(unix)]
fn same_file(file: &File, path: &Path) -> bool {
    use std::os::unix::fs::MetadataExt as _;
    match (file.metadata(), std::fs::metadata(path)) {
        (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
        _ => false,
    }
}

#[cfg(not(unix))]
fn same_file(_file: &File, path: &Path) -> bool {
    path.exists()
}

/// Takes the lock of the output `dest` (an absolute entry path) named by `flag`.
/// Fails if its folder cannot be written or another run holds it.
fn lock(flag: &str, shown: &Path, dest: &Path) -> Result<Lock> {
    let path = sibling(dest, "lock");
    let dir = parent_of(dest);
    loop {
        let mut file = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(&path)
            .with_context(|| {
                format!(
                    "{flag} {}: cannot write in the folder {}",
                    shown.display(),
                    dir.display()
                )
            })?;
        match file.try_lock() {
            Ok(()) => {}
            Err(std::fs::TryLockError::WouldBlock) => {
                let mut pid = String::new();
                let _ = file.read_to_string(&mut pid);
                let who = match pid.trim().parse::<u32>() {
                    Ok(p) => format!(" (process {p})"),
                    Err(_) => String::new(),
                };
                bail!(
                    "{flag} {}: another graphspn run{who} is writing it now; wait for that run to end or choose another output",
                    shown.display()
                );
            }
            Err(std::fs::TryLockError::Error(e)) => {
                return Err(e).with_context(|| format!("{flag} {}: locking", shown.display()));
            }
        }
        if same_file(&file, &path) {
            // For the message of a run that finds it locked; failure is harmless.
            let _ = file
                .set_len(0)
                .and_then(|()| write!(file, "{}", std::process::id()));
            return Ok(Lock { path, _file: file });
        }
        // The run that held it removed it between our open and our lock: again.
    }
}

/// Removes what killed runs left next to the output `dest` (whose lock this run
/// holds): see the module documentation.
fn clean_stale(dest: &Path) -> Result<()> {
    let dir = parent_of(dest);
    let name = dest.file_name().unwrap_or_default().to_string_lossy();
    let tmp = format!(".{name}.graphspn-tmp-");
    let old = format!(".{name}.graphspn-old-");
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Ok(());
    };
    let mut stale: Vec<(bool, PathBuf)> = Vec::new();
    for e in entries.flatten() {
        let n = e.file_name().to_string_lossy().into_owned();
        if n.starts_with(&tmp) {
            stale.push((false, e.path()));
        } else if n.starts_with(&old) {
            stale.push((true, e.path()));
        }
    }
    stale.sort();
    for (is_old, p) in stale {
        if is_old && std::fs::symlink_metadata(dest).is_err() {
            std::fs::rename(&p, dest).with_context(|| {
                format!(
                    "restoring the previous {} from {} (a run was killed while replacing it)",
                    dest.display(),
                    p.display()
                )
            })?;
        } else {
            remove_any(&p).with_context(|| {
                format!(
                    "removing {}, left by a graphspn run that was killed",
                    p.display()
                )
            })?;
        }
    }
    Ok(())
}

/// Removes a file, a symbolic link (not its target) or a folder with its content.
fn remove_any(path: &Path) -> std::io::Result<()> {
    match std::fs::symlink_metadata(path) {
        Ok(m) if m.is_dir() => std::fs::remove_dir_all(path),
        Ok(_) => std::fs::remove_file(path),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(e),
    }
}

/// Where the output folder `path` is written: the folder a symbolic link at `path`
/// points to (written there, the link kept), else the entry `path` itself. `None`
/// for a path with no parent (`/`).
fn folder_destination(path: &Path) -> Option<PathBuf> {
    let meta = std::fs::symlink_metadata(path).ok();
    if meta.as_ref().is_some_and(|m| m.file_type().is_symlink()) && path.is_dir() {
        return std::fs::canonicalize(path).ok();
    }
    if meta.as_ref().is_some_and(|m| m.is_dir()) {
        // `out/.`, `out/..`, `.`: the folder's canonical entry.
        return std::fs::canonicalize(path).ok();
    }
    entry(path)
}

impl Outputs {
    /// No inputs or outputs yet; `force` is the command's `--force`.
    pub fn new(force: bool) -> Self {
        Outputs {
            force,
            inputs: Vec::new(),
            planned: Vec::new(),
            locks: Vec::new(),
        }
    }

    /// Declares an input file named by `flag`: it must exist and be a file
    /// ([`check_input_file`]).
    pub fn input_file(&mut self, flag: &str, path: &Path) -> Result<()> {
        check_input_file(flag, path)?;
        self.input(flag, path);
        Ok(())
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

    /// Takes the lock of the output `dest`, removes what killed runs left beside it
    /// and checks that its folder takes new entries (a lock file left by an earlier
    /// run does not prove it).
    fn claim(&mut self, flag: &str, shown: &Path, dest: &Path) -> Result<()> {
        let lock = lock(flag, shown, dest)?;
        self.locks.push(lock);
        clean_stale(dest).with_context(|| format!("{flag} {}", shown.display()))?;
        let name = dest.file_name().unwrap_or_default().to_string_lossy();
        tempfile::Builder::new()
            .prefix(&format!(".{name}.graphspn-tmp-"))
            .tempfile_in(parent_of(dest))
            .with_context(|| {
                format!(
                    "{flag} {}: cannot write in the folder {}",
                    shown.display(),
                    parent_of(dest).display()
                )
            })?;
        Ok(())
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
        // Only a file (or a link: dangling, or to a file) is ever replaced; a device,
        // pipe or socket — `/dev/null`, or a link to one such as `/dev/stdout` — is
        // refused even with --force (it would be replaced by a regular file).
        if let Some(kind) = special_file(path) {
            bail!(
                "{flag} {shown}: is {kind}, not a file; give a file name (graphspn never replaces {kind})"
            );
        }
        let parent = parent_of(path);
        if !parent.is_dir() {
            bail!("{flag} {shown}: folder {} does not exist", parent.display());
        }
        let target = resolve(path).with_context(|| format!("{flag} {shown}: not a file name"))?;
        let dest = entry(path).with_context(|| format!("{flag} {shown}: not a file name"))?;
        if let Some(i) = self.clashing_input(&target, path.exists()) {
            bail!(
                "{flag} {shown}: would replace the input {} {} of this command; choose another file",
                i.flag,
                i.shown.display()
            );
        }
        if let Some((other, _)) = self.planned.iter().find(|(_, p)| *p == dest) {
            bail!("{flag} {shown}: is also the output of {other}");
        }
        self.claim(flag, path, &dest)?;
        if let Ok(m) = std::fs::symlink_metadata(path)
            && !self.force
        {
            // A link, dangling or not, is never "a file the command generated": only
            // --force replaces it.
            if m.file_type().is_symlink() {
                let dangling = if path.exists() {
                    ""
                } else {
                    ", which does not exist"
                };
                bail!(
                    "{flag} {shown}: is a symbolic link to {}{dangling}; pass --force to replace the link",
                    link_target(path)
                );
            }
            if !replace_ok {
                bail!("{flag} {shown}: exists; pass --force to replace it");
            }
        }
        self.planned.push((flag.to_string(), dest));
        Ok(())
    }

    /// Declares an output folder named by `flag`: it may be missing (it is created
    /// when writing, its missing parent folders now) or empty; a non-empty folder
    /// needs `--force` and must be one graphspn wrote (it holds [`MARKER`]); a file is
    /// refused, and so is a dangling symbolic link without `--force`. A symbolic link
    /// to a folder is followed: the folder it points to is replaced.
    pub fn folder(&mut self, flag: &str, path: &Path) -> Result<()> {
        let shown = path.display();
        if path.as_os_str().is_empty() {
            bail!("{flag}: empty folder name");
        }
        let meta = std::fs::symlink_metadata(path).ok();
        let link = meta.as_ref().is_some_and(|m| m.file_type().is_symlink());
        if path.exists() && !path.is_dir() {
            bail!("{flag} {shown}: exists and is not a folder");
        }
        if link && !path.exists() && !self.force {
            bail!(
                "{flag} {shown}: is a symbolic link to {}, which does not exist; pass --force to replace the link",
                link_target(path)
            );
        }
        let dest = folder_destination(path)
            .with_context(|| format!("{flag} {shown}: give a folder that has a parent folder"))?;
        if let Ok(cwd) = std::env::current_dir()
            && let Ok(cwd) = std::fs::canonicalize(cwd)
            && cwd.starts_with(&dest)
        {
            bail!(
                "{flag} {shown}: is the current folder or holds it; choose another folder (graphspn replaces its output folder as a whole)"
            );
        }
        if let Some(i) = self.inputs.iter().find(|i| {
            dest == i.canonical || dest.starts_with(&i.canonical) || i.canonical.starts_with(&dest)
        }) {
            bail!(
                "{flag} {shown}: overlaps the input {} {} of this command; choose another folder",
                i.flag,
                i.shown.display()
            );
        }
        if let Some((other, _)) = self.planned.iter().find(|(_, p)| *p == dest) {
            bail!("{flag} {shown}: is also the output of {other}");
        }
        if !link {
            let parent = parent_of(path);
            std::fs::create_dir_all(parent).with_context(|| {
                format!(
                    "{flag} {shown}: cannot create the folder {}",
                    parent.display()
                )
            })?;
        }
        self.claim(flag, path, &dest)?;
        if dest.is_dir() {
            let mut names = std::fs::read_dir(&dest)
                .with_context(|| format!("{flag} {shown}: cannot list the folder"))?;
            let non_empty = names.next().is_some();
            if non_empty && !self.force {
                bail!("{flag} {shown}: folder is not empty; pass --force to replace it");
            }
            if non_empty && !dest.join(MARKER).is_file() {
                bail!(
                    "{flag} {shown}: folder holds files graphspn did not write (it has no {MARKER}); --force replaces only graphspn's own output folders, as a whole: choose a new or empty folder"
                );
            }
        }
        self.planned.push((flag.to_string(), dest));
        Ok(())
    }
}

/// Writes every `(path, content)` atomically: all temporary files (in each
/// destination's folder, flushed to disk) first, then one rename each. Permissions of
/// a replaced file are kept; new files get the usual `rw-r--r--`.
pub fn write_files(files: &[(&Path, &[u8])]) -> Result<()> {
    let mut temps = Vec::with_capacity(files.len());
    for &(path, bytes) in files {
        let dir = parent_of(path);
        let name = path.file_name().unwrap_or_default().to_string_lossy();
        let mut tmp = tempfile::Builder::new()
            .prefix(&format!(".{name}.graphspn-tmp-"))
            .tempfile_in(dir)
            .with_context(|| format!("creating a temporary file in {}", dir.display()))?;
        tmp.write_all(bytes)
            .and_then(|()| tmp.flush())
            .and_then(|()| tmp.as_file().sync_all())
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

#[cfg(unix)]
fn default_folder_permissions(dir: &Path) -> Result<std::fs::Permissions> {
    use std::os::unix::fs::PermissionsExt as _;
    let mut p = std::fs::metadata(dir)?.permissions();
    p.set_mode(0o755);
    Ok(p)
}

#[cfg(not(unix))]
fn default_folder_permissions(dir: &Path) -> Result<std::fs::Permissions> {
    Ok(std::fs::metadata(dir)?.permissions())
}

/// Output of a command: a file (written atomically) or, when `None`, standard output.
pub fn emit(path: Option<&Path>, text: &str) -> Result<()> {
    match path {
        Some(p) => write_files(&[(p, text.as_bytes())]),
        None => write_stdout(text),
    }
}

/// Flushes every file under `dir` (and the folders themselves) to disk.
fn sync_tree(dir: &Path) -> std::io::Result<()> {
    for e in std::fs::read_dir(dir)? {
        let e = e?;
        if e.file_type()?.is_dir() {
            sync_tree(&e.path())?;
        } else if e.file_type()?.is_file() {
            File::open(e.path())?.sync_all()?;
        }
    }
    // Folders cannot be opened for syncing everywhere; best effort.
    if let Ok(d) = File::open(dir) {
        let _ = d.sync_all();
    }
    Ok(())
}

/// Swaps the two existing entries `a` and `b` in one step, where the platform and
/// file system can; `Ok(false)` where they cannot.
#[cfg(target_os = "linux")]
fn exchange(a: &Path, b: &Path) -> std::io::Result<bool> {
    use rustix::fs::{CWD, RenameFlags, renameat_with};
    match renameat_with(CWD, a, CWD, b, RenameFlags::EXCHANGE) {
        Ok(()) => Ok(true),
        Err(e)
            if e == rustix::io::Errno::INVAL
                || e == rustix::io::Errno::NOSYS
                || e == rustix::io::Errno::OPNOTSUPP =>
        {
            Ok(false)
        }
        Err(e) => Err(e.into()),
    }
}

#[cfg(not(target_os = "linux"))]
fn exchange(_a: &Path, _b: &Path) -> std::io::Result<bool> {
    Ok(false)
}

/// Writes the output folder `out` (declared with [`Outputs::folder`]) as a whole:
/// `make` writes the files into a fresh temporary folder beside the destination,
/// which then replaces the destination in one step (see the module documentation).
/// Nothing reaches `out` if `make` fails. Returns `out`.
pub fn write_folder(out: &Path, make: impl FnOnce(&Path) -> Result<()>) -> Result<PathBuf> {
    let dest =
        folder_destination(out).with_context(|| format!("{}: not a folder name", out.display()))?;
    let dir = parent_of(&dest);
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let name = dest.file_name().unwrap_or_default().to_string_lossy();
    let tmp = tempfile::Builder::new()
        .prefix(&format!(".{name}.graphspn-tmp-"))
        .tempdir_in(dir)
        .with_context(|| format!("creating a temporary folder in {}", dir.display()))?;
    make(tmp.path())?;
    std::fs::write(tmp.path().join(MARKER), MARKER_TEXT)
        .with_context(|| format!("writing {}", out.display()))?;
    let written = || format!("writing {}", out.display());
    // The previous folder's permissions, else the usual `rwxr-xr-x` (a temporary
    // folder is created private).
    let perms = match std::fs::metadata(&dest) {
        Ok(m) if m.is_dir() => m.permissions(),
        _ => default_folder_permissions(tmp.path())?,
    };
    std::fs::set_permissions(tmp.path(), perms).with_context(written)?;
    sync_tree(tmp.path()).with_context(written)?;
    if std::fs::symlink_metadata(&dest).is_err() {
        std::fs::rename(tmp.path(), &dest).with_context(written)?;
        let _ = tmp.keep();
    } else if exchange(tmp.path(), &dest).with_context(written)? {
        // The previous output now sits at the temporary name: delete it.
        let previous = tmp.keep();
        remove_any(&previous).with_context(|| {
            format!(
                "removing the previous {} (now {}; the next run removes it)",
                out.display(),
                previous.display()
            )
        })?;
    } else {
        // Two renames; the previous output's name shares the temporary's suffix.
        let tmp = tmp.keep();
        let suffix = tmp.file_name().unwrap_or_default().to_string_lossy();
        let suffix = suffix.rsplit('-').next().unwrap_or_default();
        let old = dir.join(format!(".{name}.graphspn-old-{suffix}"));
        if let Err(e) = std::fs::rename(&dest, &old) {
            let _ = remove_any(&tmp);
            return Err(e).with_context(written);
        }
        if let Err(e) = std::fs::rename(&tmp, &dest) {
            let _ = std::fs::rename(&old, &dest);
            let _ = remove_any(&tmp);
            return Err(e).with_context(written);
        }
        remove_any(&old).with_context(|| {
            format!(
                "removing the previous {} (now {}; the next run removes it)",
                out.display(),
                old.display()
            )
        })?;
    }
    if let Ok(d) = File::open(dir) {
        let _ = d.sync_all();
    }
    Ok(out.to_path_buf())
}

/// Writes `text` to standard output; a closed pipe (e.g. `| head`) is not an error.
pub fn write_stdout(text: &str) -> Result<()> {
    use std::io::Write;
    match std::io::stdout().lock().write_all(text.as_bytes()) {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        r => Ok(r.context("writing to standard output")?),
    }
}

/// An error and its causes on one line, each cause once: a cause whose text the
/// line already holds (library errors repeat their source in their message) is
/// skipped.
pub fn error_chain(e: &anyhow::Error) -> String {
    let mut line = String::new();
    for cause in e.chain() {
        let msg = cause.to_string();
        if line.contains(&msg) {
            continue;
        }
        if !line.is_empty() {
            line.push_str(": ");
        }
        line.push_str(&msg);
    }
    line
}
