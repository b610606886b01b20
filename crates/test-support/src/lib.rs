//! Helpers for tests that need a program the workspace does not build: a tool from a Debian
//! package (Graphviz's `dot`, say) or Python packages in a virtual environment (a reader written by
//! someone else, to check a file format against).
//!
//! A test that needs such a tool must not pass without it: [`ensure_tool`] finds the tool on
//! `PATH`, installs its Debian package when the tests run as root (as CI does, on a bare Debian
//! machine), and otherwise returns an error saying what is missing and how to get it, for the test
//! to fail with. [`python_venv`] builds one venv per workspace, under `target/test-venv`, and
//! installs the packages asked for into it. Every installation runs under one lock,
//! [`SETUP_LOCK`], held with `flock`, so test binaries running at once neither run two `apt-get`s
//! nor build the venv twice.
//!
//! ```no_run
//! let dot = test_support::ensure_tool("dot", "graphviz").unwrap_or_else(|why| panic!("{why}"));
//! if test_support::find_on_path("python3").is_none() {
//!     println!("skipped: python3 is not on PATH");
//!     return;
//! }
//! let python = test_support::python_venv(&["mcap"]).unwrap_or_else(|why| panic!("{why}"));
//! ```

pub mod browser;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The lock file every installation holds (with `flock`) while it runs.
pub const SETUP_LOCK: &str = "/tmp/tdl-test-setup.lock";

/// How long a setup step waits for the lock before giving up, in seconds: an installation running
/// in another test binary may have to download packages.
const LOCK_WAIT_SECS: &str = "1200";

/// The first executable file named `tool` in the directories of `PATH`.
pub fn find_on_path(tool: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .map(|dir| dir.join(tool))
        .find(|candidate| is_executable(candidate))
}

/// The program `tool`, found on `PATH`; when it is not there and the tests run as root, the Debian
/// package `debian_package` is installed first (`apt-get install --no-install-recommends`, after
/// `apt-get update` if the install fails, as on a machine that never fetched its package lists).
///
/// Errors say what is missing and how to install it: the test should fail with the message.
pub fn ensure_tool(tool: &str, debian_package: &str) -> Result<PathBuf, String> {
    if let Some(found) = find_on_path(tool) {
        return Ok(found);
    }
    let how = format!(
        "install the Debian package `{debian_package}` (`sudo apt-get install {debian_package}`) \
         or put `{tool}` on PATH; the tests install it themselves when they run as root"
    );
    install_package(debian_package, Some(tool))
        .map_err(|why| format!("`{tool}` is not on PATH and {why}; {how}"))?;
    find_on_path(tool).ok_or_else(|| {
        format!("`{tool}` is still not on PATH after installing `{debian_package}`; {how}")
    })
}

/// The Python interpreter of the workspace's test venv (`target/test-venv`, or
/// `$CARGO_TARGET_DIR/test-venv`), created with `python3 -m venv` if it does not exist yet, with
/// `packages` (names as `pip` knows them, or `name==version` for an exact version) installed if
/// they are not yet.
///
/// When Debian's `python3` cannot make a venv (the package `python3-venv` is missing) and the
/// tests run as root, that package is installed first. Errors say why; when `python3` itself is
/// not on `PATH` the message starts with "python3 is not on PATH" (check with
/// [`find_on_path`]`("python3")` first to skip a test instead).
pub fn python_venv(packages: &[&str]) -> Result<PathBuf, String> {
    if find_on_path("python3").is_none() {
        return Err(
            "python3 is not on PATH: install Python 3 (Debian: `python3` and \
                    `python3-venv`) to run this test"
                .into(),
        );
    }
    let dir = target_dir().join("test-venv");
    let python = dir.join("bin").join("python3");
    if has_packages(&python, packages) {
        return Ok(python);
    }
    let mut made = make_venv(&dir, packages);
    if made.is_err() && !debian_venv_works() {
        // Debian's python3 without `python3-venv` makes a venv without pip; install it and retry.
        install_package("python3-venv", None).map_err(|why| {
            format!(
                "python3 cannot make a venv and {why}; install `python3-venv` (Debian) or \
                 a Python with `venv` and `ensurepip`"
            )
        })?;
        made = make_venv(&dir, packages);
    }
    made?;
    if has_packages(&python, packages) {
        Ok(python)
    } else {
        Err(format!(
            "the packages {packages:?} are still not installed in {} after pip ran",
            dir.display()
        ))
    }
}

/// The workspace's target directory: `$CARGO_TARGET_DIR` when set, else `target` at the root.
fn target_dir() -> PathBuf {
    match std::env::var_os("CARGO_TARGET_DIR") {
        Some(dir) if !dir.is_empty() => PathBuf::from(dir),
        _ => Path::new(env!("CARGO_MANIFEST_DIR")).join("../../target"),
    }
}

/// Creates (or repairs) the venv at `dir` and pip-installs what is missing, under the lock.
fn make_venv(dir: &Path, packages: &[&str]) -> Result<(), String> {
    // A venv whose pip does not run (made by a python3 without ensurepip) is made again.
    let script = r#"set -e
dir="$1"; check="$2"; shift 2
if ! "$dir/bin/python3" -m pip --version >/dev/null 2>&1; then
    python3 -m venv --clear "$dir"
fi
if [ "$#" -gt 0 ] && ! "$dir/bin/python3" -c "$check" "$@" >/dev/null 2>&1; then
    "$dir/bin/python3" -m pip install --disable-pip-version-check --quiet "$@"
fi
"#;
    let mut args: Vec<String> = vec![
        "sh".into(),
        "-c".into(),
        script.into(),
        "sh".into(),
        dir.display().to_string(),
        HAS_PACKAGES.into(),
    ];
    args.extend(packages.iter().map(|p| (*p).to_string()));
    let out = locked(&args)?;
    if out.status.success() {
        Ok(())
    } else {
        Err(format!(
            "creating the venv {} with {packages:?} failed ({}):\n{}",
            dir.display(),
            out.status,
            tail(&out)
        ))
    }
}

/// Whether `python3 -m ensurepip --version` works, which `python3 -m venv` needs for pip.
fn debian_venv_works() -> bool {
    Command::new("python3")
        .args(["-m", "ensurepip", "--version"])
        .output()
        .is_ok_and(|out| out.status.success())
}

/// A Python program that fails unless every distribution named in its arguments is installed;
/// `name==version` asks for that exact version.
const HAS_PACKAGES: &str = "import importlib.metadata as m, sys
for p in sys.argv[1:]:
    name, _, version = p.partition('==')
    if version and m.version(name) != version: sys.exit(1)
    m.version(name)";

/// Whether `python` runs and every distribution of `packages` is installed in it (a package
/// given as `name==version` in that version).
fn has_packages(python: &Path, packages: &[&str]) -> bool {
    python.exists()
        && Command::new(python)
            .args(["-c", HAS_PACKAGES])
            .args(packages)
            .output()
            .is_ok_and(|out| out.status.success())
}

/// Installs a Debian package as root, under the lock; when `unless_tool` is given and that tool
/// is on `PATH` by the time the lock is held (another test installed it), nothing is done.
fn install_package(package: &str, unless_tool: Option<&str>) -> Result<(), String> {
    if !is_root() {
        return Err(
            "this is not root, so the tests cannot install the package themselves".to_string(),
        );
    }
    if find_on_path("apt-get").is_none() {
        return Err("there is no `apt-get` to install the package with".to_string());
    }
    let script = r#"if [ -n "$2" ] && command -v "$2" >/dev/null 2>&1; then exit 0; fi
install() { apt-get -o DPkg::Lock::Timeout=600 install -y --no-install-recommends "$1"; }
install "$1" || { apt-get -o DPkg::Lock::Timeout=600 update && install "$1"; }
"#;
    let out = locked(&[
        "sh".into(),
        "-c".into(),
        script.into(),
        "sh".into(),
        package.into(),
        unless_tool.unwrap_or("").into(),
    ])?;
    if out.status.success() {
        Ok(())
    } else {
        Err(format!(
            "`apt-get install {package}` failed ({}):\n{}",
            out.status,
            tail(&out)
        ))
    }
}

/// Runs `args` under `flock` on [`SETUP_LOCK`], non-interactively.
fn locked(args: &[String]) -> Result<Output, String> {
    if find_on_path("flock").is_none() {
        return Err(
            "`flock` (Debian package `util-linux`) is not on PATH to serialise the setup"
                .to_string(),
        );
    }
    Command::new("flock")
        .args(["-w", LOCK_WAIT_SECS, SETUP_LOCK])
        .args(args)
        .env("DEBIAN_FRONTEND", "noninteractive")
        .output()
        .map_err(|err| format!("cannot run flock: {err}"))
}

/// The last lines of a command's output, for an error message.
fn tail(out: &Output) -> String {
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let lines: Vec<&str> = text.lines().collect();
    lines[lines.len().saturating_sub(20)..].join("\n")
}

fn is_root() -> bool {
    Command::new("id")
        .arg("-u")
        .output()
        .is_ok_and(|out| out.status.success() && String::from_utf8_lossy(&out.stdout).trim() == "0")
}

#[cfg(unix)]
fn is_executable(path: &Path) -> bool {
    use std::os::unix::fs::PermissionsExt;
    std::fs::metadata(path).is_ok_and(|m| m.is_file() && m.permissions().mode() & 0o111 != 0)
}

#[cfg(not(unix))]
fn is_executable(path: &Path) -> bool {
    path.is_file()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_a_tool_every_machine_has_and_not_one_none_has() {
        let sh = find_on_path("sh").expect("every POSIX machine has sh");
        assert!(sh.is_absolute() || sh.starts_with("."), "{}", sh.display());
        assert_eq!(find_on_path("tdl-no-such-tool-anywhere"), None);
        // A tool already there is returned as is, without any installation.
        assert_eq!(ensure_tool("sh", "dash"), Ok(sh));
    }
}
