//! Building the firmware for each target and running it under QEMU, with the
//! generator's stack bounds and the checks of its ELF sections.

use super::*;

/// The firmware's `Builder` of module `name` (as its build script has it): the
/// GraphSPN of the demo model with 5 decompositions, or (`*_trees`) the demo tree
/// mixture; scalar code, seed 0.
pub fn firmware_builder(name: &str) -> Builder {
    let demo = root().join("generated/demo");
    let map = demo.join(map_file(name));
    if name.ends_with("_trees") {
        Builder::new(demo.join("tree_model.json"), map)
    } else {
        Builder::new(demo.join("model.json"), map).count(5)
    }
    .vectorisation(graphspn::codegen::Vectorisation::Scalar)
    .seed(0)
}

/// The generator's stack bounds of the firmware's scalar module `name`
/// (`STACK_BYTES_*` of the module: log-likelihood, marginals, MPE, labelled
/// log-likelihood, and last the streaming state's calls), computed by the same
/// `Builder` the firmware's build script uses.
pub fn stack_bounds(name: &str) -> [usize; 5] {
    let b = firmware_builder(name);
    let (_, r) = b.report_from_any(&b.load_any().unwrap()).unwrap();
    let file = map_file(name);
    assert!(
        r.stack_marginals <= 16 * 1024,
        "{file}: bound {} > 16 KiB",
        r.stack_marginals
    );
    [
        r.stack_log_likelihood,
        r.stack_marginals,
        r.stack_mpe,
        r.stack_log_likelihood,
        r.stack_state,
    ]
}

/// Runs `scripts/setup-mcu.sh` (the Rust targets and QEMU) once per test process;
/// panics with its output if it fails.
pub fn setup() {
    static DONE: std::sync::OnceLock<Result<(), String>> = std::sync::OnceLock::new();
    let result = DONE.get_or_init(|| {
        let out = Command::new("bash")
            .arg(root().join("scripts/setup-mcu.sh"))
            .stdin(Stdio::null())
            .output()
            .map_err(|e| format!("cannot run bash: {e}"))?;
        if out.status.success() {
            Ok(())
        } else {
            Err(format!(
                "{}{}",
                String::from_utf8_lossy(&out.stdout),
                String::from_utf8_lossy(&out.stderr)
            ))
        }
    });
    if let Err(e) = result {
        panic!("`{SETUP}` (the Rust targets and QEMU these tests need) failed:\n{e}");
    }
}

/// `cargo build --release` of the firmware for `targets` (one cargo run).
pub fn build_firmware(targets: &[&str], profile: &str, rustflags: Option<&str>) {
    setup();
    let mut cmd = Command::new(env!("CARGO"));
    cmd.current_dir(root().join("firmware"))
        .args(["build", "--quiet", "--profile", profile])
        .env("CARGO_TARGET_DIR", target_dir())
        .env_remove("RUSTFLAGS")
        .env_remove("CARGO_ENCODED_RUSTFLAGS");
    for t in targets {
        cmd.args(["--target", t]);
    }
    if let Some(f) = rustflags {
        cmd.env("RUSTFLAGS", f);
    }
    let out = cmd.output().unwrap();
    assert!(
        out.status.success(),
        "building the firmware for {targets:?} failed (missing Rust targets? run `{SETUP}`):\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

pub fn elf(target: &str, profile: &str) -> PathBuf {
    let dir = if profile == "dev" { "debug" } else { profile };
    target_dir()
        .join(target)
        .join(dir)
        .join("graphspn-firmware")
}

/// QEMU's folder as `scripts/setup-mcu.sh` unpacks it.
pub fn qemu_dir() -> PathBuf {
    std::env::var_os("GRAPHSPN_MCU_TOOLS")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(std::env::var_os("HOME").expect("HOME is set"))
                .join(".cache/graphspn/mcu-tools")
        })
        .join("qemu")
}

/// A command running QEMU binary `name`: from the setup script's cache, else from
/// `PATH`; fails naming the setup script if neither has it.
pub fn qemu(name: &str) -> Command {
    setup();
    let dir = qemu_dir();
    if dir.join(".complete").exists() {
        let mut cmd = Command::new(dir.join("usr/bin").join(name));
        let mut libs = format!(
            "{}:{}",
            dir.join("usr/lib/x86_64-linux-gnu").display(),
            dir.join("lib/x86_64-linux-gnu").display()
        );
        if let Some(old) = std::env::var_os("LD_LIBRARY_PATH") {
            libs = format!("{libs}:{}", old.to_string_lossy());
        }
        cmd.env("LD_LIBRARY_PATH", libs);
        return cmd;
    }
    let on_path = std::env::var_os("PATH")
        .is_some_and(|p| std::env::split_paths(&p).any(|d| d.join(name).is_file()));
    assert!(
        on_path,
        "QEMU ({name}) is neither in {} nor on PATH, though `{SETUP}` succeeded",
        dir.display()
    );
    Command::new(name)
}

/// Runs `cmd` to completion within [`QEMU_TIMEOUT`]; returns stdout.
pub fn run_bounded(mut cmd: Command, what: &str) -> String {
    let mut child = cmd
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("{what}: cannot start ({e}); run `{SETUP}`"));
    let mut stdout = child.stdout.take().unwrap();
    let reader = std::thread::spawn(move || {
        let mut s = String::new();
        stdout.read_to_string(&mut s).map(|_| s)
    });
    let start = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if start.elapsed() > QEMU_TIMEOUT {
            let _ = child.kill();
            let _ = child.wait();
            panic!("{what}: still running after {QEMU_TIMEOUT:?}; killed");
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    let out = reader.join().unwrap().unwrap();
    let mut err = String::new();
    let _ = child.stderr.take().unwrap().read_to_string(&mut err);
    assert!(
        status.success(),
        "{what}: exit status {status}\nstdout:\n{out}\nstderr:\n{err}"
    );
    out
}

/// Runs the firmware built for `mcu` (profile `profile`) under QEMU.
pub fn run_qemu(mcu: &Mcu, profile: &str) -> Report {
    let kernel = elf(mcu.target, profile);
    let mut cmd = qemu(mcu.qemu);
    cmd.args(["-M", mcu.machine]).args(mcu.args);
    cmd.args(["-nographic", "-monitor", "none", "-icount", "shift=0"])
        .arg("-kernel")
        .arg(&kernel);
    parse(&run_bounded(
        cmd,
        &format!("QEMU {} {}", mcu.target, kernel.display()),
    ))
}

/// Size in bytes of section `name` of ELF `elf` (`size -A` from binutils; 0 when
/// the section is absent).
pub fn section_bytes(elf: &std::path::Path, name: &str) -> u64 {
    let out = Command::new("size")
        .arg("-A")
        .arg(elf)
        .output()
        .expect("running `size` (binutils)");
    assert!(out.status.success(), "size -A {}", elf.display());
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .find_map(|l| {
            let mut w = l.split_whitespace();
            (w.next() == Some(name)).then(|| w.next()?.parse().ok())?
        })
        .unwrap_or(0)
}

/// `State::new()` is all zeros, so the firmware's buffers start as a `memset` of
/// `.bss`: no object in the ELF is as large as the smallest map's `State`
/// (`smallest` bytes), as a constant initial image of a state would be (a non-zero
/// field in `new` once put an 88 KB image of the buffers in flash).
pub fn assert_no_state_image(elf: &std::path::Path, smallest: usize, target: &str) {
    let out = Command::new("nm")
        .args(["-S", "-t", "d", "--size-sort"])
        .arg(elf)
        .output()
        .expect("running `nm` (binutils)");
    assert!(out.status.success(), "nm -S {}", elf.display());
    let text = String::from_utf8_lossy(&out.stdout);
    let largest = text
        .lines()
        .filter_map(|l| {
            let w: Vec<&str> = l.split_whitespace().collect();
            let data = matches!(w.get(2).copied(), Some("r" | "R" | "d" | "D"));
            data.then(|| Some((w.get(1)?.parse::<usize>().ok()?, w.get(3)?.to_string())))?
        })
        .max();
    if let Some((size, name)) = largest {
        assert!(
            size < smallest,
            "{target}: {name} holds {size} bytes of initialised data, at least a whole \
             State ({smallest} B): State::new() must stay all zeros"
        );
    }
}
