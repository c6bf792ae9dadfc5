//! The npm packages the standard-tiles tests read relief's tiles with
//! (CesiumJS, MapLibre GL JS, gltf-validator): `tests/npm/package.json`
//! and its committed lockfile, installed with `npm ci` into
//! `tests/npm/node_modules` once, by the first test that asks. Nothing from
//! npm ships in reliefd.

use std::fs::File;
use std::path::PathBuf;
use std::process::Command;

use anyhow::{Context, bail};

/// The folder holding `package.json`.
pub fn folder() -> PathBuf {
    crate::workspace_root().join("tests/npm")
}

/// True when `node` and `npm` are here; else a note on stderr, and the
/// test skips (scripts/setup.sh installs them; CI has them).
pub fn available() -> bool {
    let found = ["node", "npm"].iter().all(|tool| Command::new(tool).arg("--version").output().is_ok());
    if !found {
        eprintln!("SKIPPED: no node or npm (scripts/setup.sh installs them; CI has them)");
    }
    found
}

/// `tests/npm/node_modules`, installed with `npm ci` from the lockfile when
/// it is missing or older than the lockfile. Test binaries run at once:
/// a file lock lets one install while the others wait.
pub fn node_modules() -> anyhow::Result<PathBuf> {
    let dir = folder();
    let modules = dir.join("node_modules");
    let lock =
        File::create(std::env::temp_dir().join("relief-tests-npm.lock")).context("cannot make npm's lock file")?;
    lock.lock().context("cannot take npm's lock")?;
    let stamp = modules.join(".relief-installed");
    let lockfile = dir.join("package-lock.json");
    let fresh = match (std::fs::metadata(&stamp), std::fs::metadata(&lockfile)) {
        (Ok(s), Ok(l)) => s.modified()? >= l.modified()?,
        _ => false,
    };
    if !fresh {
        let out = Command::new("npm")
            .args(["ci", "--no-audit", "--no-fund", "--loglevel=error"])
            .current_dir(&dir)
            .output()
            .context("cannot run npm (scripts/setup.sh installs it)")?;
        if !out.status.success() {
            bail!("npm ci in {} failed: {}", dir.display(), String::from_utf8_lossy(&out.stderr));
        }
        std::fs::write(&stamp, b"npm ci from package-lock.json\n")?;
    }
    Ok(modules)
}
