//! Crash safety and concurrency of every output (`src/cli/output.rs`), tested the way
//! crash-safe systems are: real `graphspn` runs (`train` and `compile` writing a
//! file, `reproduce --quick` writing a folder) are killed with SIGKILL after seeded
//! random delays, and what remains must be the previous output or the complete new
//! one, with nothing beside it but the documented temporaries
//! (`.NAME.graphspn-lock`, `.NAME.graphspn-tmp-XXXXXX`, `.NAME.graphspn-old-XXXXXX`),
//! all of which the next run removes. Some kills of `reproduce` wait for its
//! temporary folder to appear, so they land while the output is being written and
//! swapped in. Also: two runs writing the same output at once (one wins, the other
//! stops at once naming the output), dangling symbolic links, unwritable locations,
//! and recovery from a swap interrupted between its two renames.
//!
//! Every random step takes its seed from `GRAPHSPN_CRASH_SEED` (default 23, printed);
//! `GRAPHSPN_CRASH_KILLS=N` scales the number of kills per command (default 1).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn repo(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

/// The binary, quiet, with the shipped data.
fn bin() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_graphspn"));
    c.env_remove("GRAPHSPN_DATA")
        .env("RUST_BACKTRACE", "0")
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    c
}

fn seed(test: u64) -> u64 {
    let s = std::env::var("GRAPHSPN_CRASH_SEED")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(23);
    eprintln!("GRAPHSPN_CRASH_SEED={s} (test {test})");
    s ^ (test << 32)
}

/// Kills per command, times `base`.
fn kills(base: usize) -> usize {
    base * std::env::var("GRAPHSPN_CRASH_KILLS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(1)
}

fn run(cmd: &mut Command) -> Output {
    cmd.output().expect("graphspn starts")
}

fn run_ok(cmd: &mut Command) -> Duration {
    let t = Instant::now();
    let out = run(cmd);
    assert!(
        out.status.success(),
        "graphspn failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    t.elapsed()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Names in `dir` that graphspn's output code made (`*.graphspn-*`).
fn leftovers(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains(".graphspn-"))
        .collect();
    v.sort();
    v
}

/// Whether `name` is one of the documented names next to the output `out`.
fn documented(out: &str, name: &str) -> bool {
    let Some(rest) = name.strip_prefix(&format!(".{out}.graphspn-")) else {
        return false;
    };
    let random = |s: &str| s.len() == 6 && s.chars().all(|c| c.is_ascii_alphanumeric());
    rest == "lock"
        || rest.strip_prefix("tmp-").is_some_and(random)
        || rest.strip_prefix("old-").is_some_and(random)
}

/// Asserts that `dir` holds nothing of graphspn's but documented temporaries of `out`.
fn only_documented(dir: &Path, out: &str, when: &str) {
    for n in leftovers(dir) {
        assert!(
            documented(out, &n),
            "{when}: {n} in {} is no documented temporary of {out}",
            dir.display()
        );
    }
}

/// Every file under `dir` (relative path, content).
fn tree(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                let rel = p.strip_prefix(dir).unwrap().to_path_buf();
                out.insert(rel, std::fs::read(&p).unwrap());
            }
        }
    }
    out
}

/// Starts `cmd` and SIGKILLs it after `delay` (unless it ended before); returns
/// whether it was killed.
fn kill_after(mut cmd: Command, delay: Duration) -> bool {
    let mut child = cmd.spawn().expect("graphspn starts");
    let start = Instant::now();
    loop {
        if child.try_wait().unwrap().is_some() {
            return false;
        }
        if start.elapsed() >= delay {
            break;
        }
        std::thread::sleep(Duration::from_micros(500));
    }
    kill(&mut child)
}

/// SIGKILL (`Child::kill` on Unix) and reap; whether the process was still running.
fn kill(child: &mut Child) -> bool {
    let running = child.try_wait().unwrap().is_none();
    let _ = child.kill();
    let _ = child.wait();
    running
}

/// One file output under random kills: `make(seed)` is the command writing
/// `dir/out` (replacing it without --force or with it, as the command needs); the
/// output of seed 1 is the previous one, of seed 2 the new one.
fn file_output_survives_kills(test: u64, out: &str, make: impl Fn(&Path, u64) -> Command) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed(test));
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(out);
    run_ok(&mut make(&path, 1));
    let previous = std::fs::read(&path).unwrap();
    run_ok(&mut make(&path, 2));
    let new = std::fs::read(&path).unwrap();
    // Deterministic outputs: a second run gives the same bytes.
    std::fs::write(&path, &previous).unwrap();
    let took = run_ok(&mut make(&path, 2));
    assert_eq!(
        std::fs::read(&path).unwrap(),
        new,
        "{out}: not deterministic"
    );
    assert_ne!(previous, new, "{out}: the two seeds give the same output");
    let (mut killed, mut finished, mut new_outputs) = (0, 0, 0);
    for i in 0..kills(12) {
        std::fs::write(&path, &previous).unwrap();
        let delay = took.mul_f64(rng.random_range(0.0..1.2));
        if kill_after(make(&path, 2), delay) {
            killed += 1;
        } else {
            finished += 1;
        }
        let now = std::fs::read(&path).unwrap();
        assert!(
            now == previous || now == new,
            "{out}: kill {i} after {delay:?} left neither the previous nor the complete new output ({} bytes)",
            now.len()
        );
        new_outputs += usize::from(now == new);
        only_documented(dir.path(), out, &format!("kill {i} after {delay:?}"));
    }
    eprintln!(
        "{out}: {killed} runs killed, {finished} finished first; {new_outputs} of them left the new output"
    );
    // The next complete run removes whatever the killed ones left.
    run_ok(&mut make(&path, 2));
    assert_eq!(std::fs::read(&path).unwrap(), new);
    assert_eq!(leftovers(dir.path()), Vec::<String>::new());
}

#[test]
fn train_killed_at_random_leaves_the_previous_or_the_new_model() {
    file_output_survives_kills(1, "model.json", |path, seed| {
        let mut c = bin();
        c.args([
            "train",
            "--buildings",
            "Stockholm",
            "--epochs",
            "2",
            "--force",
        ])
        .args(["--seed", &seed.to_string(), "--out"])
        .arg(path);
        c
    });
}

#[test]
fn compile_killed_at_random_leaves_the_previous_or_the_new_source() {
    // `compile` replaces a file it generated without --force.
    file_output_survives_kills(2, "floor.rs", |path, seed| {
        let mut c = bin();
        c.args(["compile", "--module", "floor", "--count", "3"])
            .args(["--seed", &seed.to_string(), "--model"])
            .arg(repo("generated/demo/model.json"))
            .arg("--map")
            .arg(repo("generated/demo/floor.json"))
            .arg("--out")
            .arg(path);
        c
    });
}

/// `reproduce --quick` (reduced further: one level, no novelty) into `out`.
fn reproduce(out: &Path, seed: u64) -> Command {
    let mut c = bin();
    c.args(["reproduce", "--quick", "--tiny-grid", "--no-novelty"])
        .args([
            "--levels",
            "2",
            "--force",
            "--seed",
            &seed.to_string(),
            "--out",
        ])
        .arg(out);
    c
}

/// Whether `found` is a complete new output folder: the files of `new` (a reference
/// run of the same command; run times in the numbers differ between runs), each
/// complete (JSON parses, SVG closed, Markdown ends its last line), and none of those
/// that differ between `previous` and `new` still the previous one's.
fn complete_new(
    found: &BTreeMap<PathBuf, Vec<u8>>,
    previous: &BTreeMap<PathBuf, Vec<u8>>,
    new: &BTreeMap<PathBuf, Vec<u8>>,
) -> bool {
    found.keys().eq(new.keys())
        && found.contains_key(Path::new(".graphspn-output"))
        && found.iter().all(|(name, bytes)| {
            let complete = match name.extension().and_then(|x| x.to_str()) {
                Some("json") => serde_json::from_slice::<serde_json::Value>(bytes).is_ok(),
                Some("svg") => bytes.trim_ascii_end().ends_with(b"</svg>"),
                Some("md") => bytes.ends_with(b"\n"),
                _ => !bytes.is_empty(),
            };
            let stale = previous.get(name) == Some(bytes) && new.get(name) != Some(bytes);
            complete && !stale
        })
}

#[test]
fn reproduce_killed_at_random_leaves_the_previous_or_the_complete_new_folder() {
    let mut rng = ChaCha8Rng::seed_from_u64(seed(3));
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    run_ok(&mut reproduce(&out, 1));
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt as _;
        let mode = std::fs::metadata(&out).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o755, "a new output folder is rwxr-xr-x");
    }
    let previous = tree(&out);
    let took = run_ok(&mut reproduce(&out, 2));
    let new = tree(&out);
    assert!(complete_new(&new, &previous, &new), "{:?}", new.keys());
    assert_ne!(previous, new);
    // How long the writing takes: from the temporary folder's appearance to the end.
    let mut child = reproduce(&out, 2).spawn().unwrap();
    wait_for_temporary_folder(dir.path(), &out, &mut child);
    let t = Instant::now();
    assert!(child.wait().unwrap().success());
    let writing = t.elapsed();
    eprintln!("reproduce: {took:?} in all, {writing:?} writing");
    let mut outcomes = BTreeMap::<&str, usize>::new();
    for i in 0..kills(6) {
        // The previous output back in place (a complete copy of it).
        std::fs::remove_dir_all(&out).unwrap();
        std::fs::create_dir(&out).unwrap();
        for (p, bytes) in &previous {
            std::fs::write(out.join(p), bytes).unwrap();
        }
        let delay = took.mul_f64(rng.random_range(0.0..1.0));
        let killed = if i % 2 == 0 {
            // At a random instant of the run.
            kill_after(reproduce(&out, 2), delay)
        } else {
            // While the output is written and swapped in: once the temporary folder
            // appears, after a random part of the writing time.
            let mut child = reproduce(&out, 2).spawn().unwrap();
            let extra = writing.mul_f64(rng.random_range(0.0..1.3));
            wait_for_temporary_folder(dir.path(), &out, &mut child);
            std::thread::sleep(extra);
            kill(&mut child)
        };
        let now = tree(&out);
        let outcome = if now == previous {
            "previous"
        } else if complete_new(&now, &previous, &new) {
            "new"
        } else {
            panic!(
                "kill {i}: {} holds neither the previous nor a complete new output: {:?}",
                out.display(),
                now.keys()
            )
        };
        *outcomes.entry(outcome).or_default() += 1;
        only_documented(dir.path(), "out", &format!("kill {i}"));
        eprintln!(
            "kill {i} ({}): {outcome}, left {:?}",
            if killed { "killed" } else { "had ended" },
            leftovers(dir.path())
        );
    }
    eprintln!("outcomes: {outcomes:?}");
    // A replaced folder keeps its permissions.
    #[cfg(unix)]
    let mode = |p: &Path| {
        use std::os::unix::fs::PermissionsExt as _;
        std::fs::metadata(p).unwrap().permissions().mode() & 0o777
    };
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt as _;
        std::fs::set_permissions(&out, std::fs::Permissions::from_mode(0o750)).unwrap();
    }
    run_ok(&mut reproduce(&out, 2));
    #[cfg(unix)]
    assert_eq!(mode(&out), 0o750);
    assert!(complete_new(&tree(&out), &previous, &new));
    assert_eq!(leftovers(dir.path()), Vec::<String>::new());
}

/// Names and sizes of the files in `dir`.
fn listing(dir: &Path) -> Vec<(std::ffi::OsString, u64)> {
    let mut v: Vec<_> = std::fs::read_dir(dir)
        .map(|r| {
            r.flatten()
                .map(|e| (e.file_name(), e.metadata().map_or(0, |m| m.len())))
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}

/// Polls until the output starts being written, or `child` ends: a temporary output
/// folder appears in `dir` (the declaration's writability probe is a temporary
/// file of the same pattern), or anything in the output folder `out` changes.
fn wait_for_temporary_folder(dir: &Path, out: &Path, child: &mut Child) {
    let before = listing(out);
    loop {
        let building = leftovers(dir)
            .iter()
            .any(|n| n.contains("graphspn-tmp") && dir.join(n).is_dir());
        if building || listing(out) != before || child.try_wait().unwrap().is_some() {
            return;
        }
        std::thread::sleep(Duration::from_millis(1));
    }
}

/// Polls until the lock file `dir/name` holds its owner's process id (written once
/// locked) or `child` ends; false if it never did.
fn wait_for(dir: &Path, name: &str, child: &mut Child) -> bool {
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(60) {
        if std::fs::read_to_string(dir.join(name)).is_ok_and(|s| !s.trim().is_empty()) {
            return true;
        }
        if child.try_wait().unwrap().is_some() {
            return false;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    false
}

#[test]
fn a_second_run_writing_the_same_output_stops_at_once_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    // Folder output: the first run holds the output's lock while it computes.
    let mut first = reproduce(&out, 1).spawn().unwrap();
    assert!(
        wait_for(dir.path(), ".out.graphspn-lock", &mut first),
        "the first run took no lock"
    );
    let t = Instant::now();
    let second = run(&mut reproduce(&out, 2));
    let second_took = t.elapsed();
    let first = first.wait_with_output().unwrap();
    assert!(first.status.success(), "{}", stderr(&first));
    assert_eq!(second.status.code(), Some(1));
    let msg = stderr(&second);
    assert!(
        msg.contains("--out") && msg.contains(&out.display().to_string()),
        "{msg}"
    );
    assert!(
        msg.contains("another graphspn run") && msg.lines().count() == 1,
        "{msg}"
    );
    assert!(
        second_took < Duration::from_secs(5),
        "refused after {second_took:?}"
    );
    assert!(tree(&out).contains_key(Path::new("REPORT.md")));
    assert_eq!(leftovers(dir.path()), Vec::<String>::new());

    // File outputs, both started at once with --force: exactly one writes, the other
    // fails naming the output (or, if the first ended before the second began, both
    // succeed one after the other; never two at once).
    let model = dir.path().join("model.json");
    let train = || {
        let mut c = bin();
        c.args(["train", "--buildings", "Freiburg,Saarbrucken,Stockholm"])
            .args(["--force", "--out"])
            .arg(&model);
        c
    };
    let (a, b) = (train().spawn().unwrap(), train().spawn().unwrap());
    let (a, b) = (a.wait_with_output().unwrap(), b.wait_with_output().unwrap());
    let ok = [&a, &b].iter().filter(|o| o.status.success()).count();
    assert!(ok >= 1, "{} / {}", stderr(&a), stderr(&b));
    for o in [&a, &b] {
        if !o.status.success() {
            assert!(stderr(o).contains("another graphspn run"), "{}", stderr(o));
        }
    }
    eprintln!("two concurrent trains: {ok} succeeded");
    assert!(
        std::fs::read_to_string(&model)
            .unwrap()
            .contains("\"spns\"")
    );
    assert_eq!(leftovers(dir.path()), Vec::<String>::new());
}

#[cfg(unix)]
#[test]
fn a_dangling_symlink_is_replaced_only_with_force() {
    let dir = tempfile::tempdir().unwrap();
    let train = |out: &Path, force: bool| {
        let mut c = bin();
        c.args([
            "train",
            "--buildings",
            "Stockholm",
            "--epochs",
            "1",
            "--out",
        ])
        .arg(out);
        if force {
            c.arg("--force");
        }
        run(&mut c)
    };
    let link = dir.path().join("model.json");
    std::os::unix::fs::symlink("nowhere/model.json", &link).unwrap();
    let refused = train(&link, false);
    assert_eq!(refused.status.code(), Some(1));
    let msg = stderr(&refused);
    assert!(
        msg.contains("symbolic link") && msg.contains("--force"),
        "{msg}"
    );
    assert!(
        std::fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink()
    );
    assert!(train(&link, true).status.success());
    let m = std::fs::symlink_metadata(&link).unwrap();
    assert!(m.is_file(), "the link is replaced by the model");
    assert!(
        !dir.path().join("nowhere").exists(),
        "its target is not created"
    );

    // An output folder: refused before computing, the link untouched.
    let folder = dir.path().join("out");
    std::os::unix::fs::symlink("missing", &folder).unwrap();
    let mut c = bin();
    c.args(["reproduce", "--quick", "--out"]).arg(&folder);
    let t = Instant::now();
    let refused = run(&mut c);
    assert_eq!(refused.status.code(), Some(1), "{}", stderr(&refused));
    assert!(t.elapsed() < Duration::from_secs(5));
    assert!(stderr(&refused).contains("symbolic link"));
    assert_eq!(std::fs::read_link(&folder).unwrap(), Path::new("missing"));
    assert_eq!(leftovers(dir.path()), Vec::<String>::new());
}

/// A device, pipe or socket at an output's path (or a link to one) is never replaced,
/// even with --force: `--out /dev/null` would otherwise turn the system's `/dev/null`
/// into an SVG file when run as root. Tried on a named pipe and a link to
/// `/dev/null` in a scratch folder, so that a regression damages nothing.
#[cfg(unix)]
#[test]
fn devices_and_pipes_are_never_replaced() {
    use std::os::unix::fs::FileTypeExt;
    let dir = tempfile::tempdir().unwrap();
    let pipe = dir.path().join("pipe.svg");
    let made = Command::new("mkfifo").arg(&pipe).status();
    let null_link = dir.path().join("null.svg");
    std::os::unix::fs::symlink("/dev/null", &null_link).unwrap();
    let mut outs = vec![(null_link.clone(), "a character device")];
    if made.is_ok_and(|s| s.success()) {
        outs.push((pipe.clone(), "a named pipe"));
    }
    for (out, kind) in outs {
        for force in [false, true] {
            let mut c = bin();
            c.args(["render", "--synthetic", "10", "--out"]).arg(&out);
            if force {
                c.arg("--force");
            }
            let o = run(&mut c);
            assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
            assert!(
                stderr(&o).contains(&format!("is {kind}, not a file")),
                "{}",
                stderr(&o)
            );
        }
    }
    assert!(std::fs::read_link(&null_link).is_ok(), "the link is kept");
    if pipe.exists() {
        let t = std::fs::symlink_metadata(&pipe).unwrap().file_type();
        assert!(t.is_fifo(), "the pipe is kept");
    }
}

#[test]
fn unwritable_locations_and_foreign_folders_are_refused_before_computing() {
    let dir = tempfile::tempdir().unwrap();
    let mut places = Vec::new();
    // /sys refuses new files even to root.
    if Path::new("/sys/kernel").is_dir() {
        places.push(PathBuf::from("/sys"));
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt as _;
        let ro = dir.path().join("read-only");
        std::fs::create_dir(&ro).unwrap();
        std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o555)).unwrap();
        // Root writes anyway: the check is meaningful only for other users.
        if std::fs::File::create(ro.join("probe")).is_err() {
            places.push(ro);
        }
    }
    assert!(!places.is_empty(), "no unwritable folder to test with");
    for place in places {
        for args in [
            vec!["train", "--buildings", "Freiburg,Saarbrucken,Stockholm"],
            vec!["reproduce"],
        ] {
            let t = Instant::now();
            let o = run(bin()
                .args(&args)
                .arg("--out")
                .arg(place.join("graphspn-out")));
            assert_eq!(o.status.code(), Some(1), "{args:?}: {}", stderr(&o));
            let msg = stderr(&o);
            assert!(
                msg.contains("--out") && msg.contains("cannot"),
                "{args:?}: {msg}"
            );
            assert!(t.elapsed() < Duration::from_secs(5), "{args:?}: {msg}");
        }
    }
    // A non-empty folder graphspn did not write is not replaced, --force or not.
    let mine = dir.path().join("mine");
    std::fs::create_dir(&mine).unwrap();
    std::fs::write(mine.join("notes.txt"), "keep me").unwrap();
    let o = run(bin().args(["reproduce", "--force", "--out"]).arg(&mine));
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("did not write"), "{}", stderr(&o));
    assert_eq!(
        std::fs::read_to_string(mine.join("notes.txt")).unwrap(),
        "keep me"
    );
}

#[test]
fn the_next_run_cleans_what_a_killed_run_left() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    // A swap by two renames interrupted between them: the previous output under its
    // -old- name, nothing at `out`; a half-written new one; a lock no one holds.
    let old = dir.path().join(".out.graphspn-old-Ab12Cd");
    std::fs::create_dir(&old).unwrap();
    std::fs::write(old.join(".graphspn-output"), "").unwrap();
    std::fs::write(old.join("REPORT.md"), "# previous\n").unwrap();
    let tmp = dir.path().join(".out.graphspn-tmp-Ab12Cd");
    std::fs::create_dir(&tmp).unwrap();
    std::fs::write(tmp.join("REPORT.md"), "# half").unwrap();
    std::fs::write(dir.path().join(".out.graphspn-lock"), "1").unwrap();
    std::fs::write(dir.path().join(".model.json.graphspn-tmp-Zz99Yy"), "{").unwrap();
    // A run that declares `out` (and then stops at a bad argument) cleans up.
    let o = run(bin()
        .args(["reproduce", "--levels", "9", "--force", "--out"])
        .arg(&out));
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("--levels 9"), "{}", stderr(&o));
    assert_eq!(
        std::fs::read_to_string(out.join("REPORT.md")).unwrap(),
        "# previous\n",
        "the previous output is back"
    );
    // Only the temporaries of `out`: model.json's wait for a run writing model.json.
    assert_eq!(
        leftovers(dir.path()),
        vec![".model.json.graphspn-tmp-Zz99Yy".to_string()]
    );
    run_ok(
        bin()
            .args(["generate", "--places", "20", "--seed", "1", "--out"])
            .arg(dir.path().join("model.json")),
    );
    assert_eq!(leftovers(dir.path()), Vec::<String>::new());
}
