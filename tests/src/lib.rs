//! Helpers for relief's end-to-end tests: start the real `reliefd` on
//! loopback, make analytic fixtures with GDAL, and ask GDAL itself for
//! reference values; for the benches and `make accuracy` too, a drawn
//! surface's error against the demo's formula (`surface`).

pub mod arcgis;
pub mod bench;
pub mod browser;
pub mod consumers;
pub mod daemon;
pub mod edit;
pub mod http;
pub mod npm;
pub mod pages;
pub mod probe;
pub mod qgis;
pub mod redis;
pub mod reference;
pub mod s3;
pub mod scenes;
pub mod surface;
pub mod tiles;
pub mod vectors;

/// Analytic fixtures live with the example scenes.
pub use relief_examples as fixtures;

use std::path::PathBuf;

/// The workspace root.
pub fn workspace_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// A binary of the workspace, built next to the running test.
pub fn bin(name: &str) -> PathBuf {
    let exe = std::env::current_exe().expect("the test knows where it runs from");
    // target/<profile>/deps/<test> -> target/<profile>/<name>
    let dir = exe.parent().and_then(|deps| deps.parent()).expect("tests run from target/<profile>/deps");
    dir.join(name)
}

/// `../shared/data` beside the checkout (or `RELIEF_SHARED_DATA`), which CI
/// always has. None, with a note on stderr, in a clone without it.
pub fn shared_data(test: &str) -> Option<PathBuf> {
    let dir = std::env::var_os("RELIEF_SHARED_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| workspace_root().join("../shared/data"));
    if dir.join("SOURCES.md").exists() {
        Some(dir)
    } else {
        eprintln!("skipping {test}: it needs the shared GIS data at {} (CI has it)", dir.display());
        None
    }
}

/// Debian's Python, which has GDAL's and QGIS's bindings (scripts/setup.sh).
pub const PYTHON: &str = "/usr/bin/python3";

/// True when Debian's Python runs `code` (an import check): the editors
/// the tests drive need it. CI must have it (`packages`, installed by
/// scripts/setup.sh); elsewhere `test` is skipped with a note.
pub fn python_can(test: &str, code: &str, packages: &str) -> bool {
    use std::process::{Command, Stdio};
    let found = Command::new(PYTHON)
        .args(["-c", code])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    assert!(found || std::env::var_os("CI").is_none(), "{test}: CI must have {packages} (scripts/setup.sh)");
    if !found {
        eprintln!("skipping {test}: it needs Debian's {packages} (scripts/setup.sh installs them)");
    }
    found
}

/// The machine a benchmark ran on, for its table: CPU model and cores.
pub fn machine() -> String {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines().find(|l| l.starts_with("model name")).map(|l| l.split(':').nth(1).unwrap_or("").trim().to_owned())
        })
        .unwrap_or_else(|| "unknown CPU".into());
    format!("{cpu}, {} cores visible", std::thread::available_parallelism().map_or(0, std::num::NonZero::get))
}
