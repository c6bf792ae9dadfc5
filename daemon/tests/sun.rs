//! The sun against an independent reference: pvlib's implementation of
//! NREL's SPA (installed from the Python package registry into a venv under
//! `target/`), at 1,000 random times and places and the polar cases.
//! Tolerance: 0.01 degrees in elevation and azimuth (azimuth is left out
//! within 0.5 degrees of the zenith, where it has no meaning).

#![allow(clippy::unwrap_used, clippy::print_stdout, reason = "a test")]

use std::fmt::Write;
use std::path::{Path, PathBuf};
use std::process::Command;

use chrono::{DateTime, FixedOffset};
use relief_daemon::sun::sun_at;
use relief_examples::Lcg;

const TOLERANCE_DEG: f64 = 0.01;

/// A venv with pvlib under the target folder, made once.
fn pvlib_python() -> PathBuf {
    let target = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target");
    let venv = target.join("pvlib-venv");
    let python = venv.join("bin/python");
    let has =
        |python: &Path| Command::new(python).args(["-c", "import pvlib"]).output().is_ok_and(|o| o.status.success());
    if !has(&python) {
        let made = Command::new("python3").args(["-m", "venv"]).arg(&venv).status().unwrap();
        assert!(made.success(), "python3 -m venv {} failed (python3-venv is in scripts/setup.sh)", venv.display());
        let pip = Command::new(venv.join("bin/pip"))
            .args(["install", "--quiet", "--disable-pip-version-check", "pvlib"])
            .output()
            .unwrap();
        assert!(pip.status.success(), "pip install pvlib failed: {}", String::from_utf8_lossy(&pip.stderr));
    }
    python
}

const PVLIB: &str = r"
import sys, csv
import pandas as pd
from pvlib import solarposition
out = csv.writer(sys.stdout)
for time, lat, lon, dt in csv.reader(open(sys.argv[1])):
    t = pd.DatetimeIndex([pd.Timestamp(time)])
    p = solarposition.spa_python(t, float(lat), float(lon), altitude=0.0, delta_t=float(dt), how='numpy')
    out.writerow([repr(float(p['azimuth'].iloc[0])), repr(float(p['elevation'].iloc[0]))])
";

#[test]
fn the_sun_agrees_with_pvlib_spa_within_a_hundredth_of_a_degree() {
    let mut rng = Lcg(0x5017_2026);
    // Random instants 1950..2100 and places; then the cases a shadow study
    // or a polar scene meets: midnight sun and polar night, both poles'
    // neighbourhoods, the antimeridian, the zenith at the subsolar point.
    let mut cases: Vec<(DateTime<FixedOffset>, f64, f64)> = (0..1000)
        .map(|_| {
            let seconds = rng.range(-631_152_000.0, 4_102_444_800.0) as i64;
            let time = DateTime::from_timestamp(seconds, 0).unwrap().fixed_offset();
            (time, rng.range(-89.9, 89.9), rng.range(-180.0, 180.0))
        })
        .collect();
    let at = |t: &str| DateTime::parse_from_rfc3339(t).unwrap();
    cases.extend([
        (at("2026-06-21T00:00:00+02:00"), 78.22, 15.65), // Longyearbyen: midnight sun
        (at("2026-12-21T12:00:00+01:00"), 78.22, 15.65), // polar night at noon
        (at("2026-06-21T12:00:00Z"), 89.9, 0.0),
        (at("2026-12-21T12:00:00Z"), -89.9, 135.0),
        (at("2026-03-20T06:00:00Z"), 0.0, 179.99),
        (at("2026-03-20T06:00:00Z"), 0.0, -179.99),
        (at("2026-06-21T12:00:00Z"), 23.44, 0.0), // near the zenith
    ]);
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("cases.csv");
    let mut mine = Vec::new();
    let mut text = String::new();
    for (time, lat, lon) in &cases {
        let dt = solar_positioning::delta_t::estimate_from_date_like(time).unwrap();
        mine.push(sun_at(time, *lon, *lat, dt).unwrap());
        writeln!(text, "{},{lat},{lon},{dt}", time.to_rfc3339()).unwrap();
    }
    std::fs::write(&input, text).unwrap();
    let output = Command::new(pvlib_python()).args(["-c", PVLIB]).arg(&input).output().unwrap();
    assert!(output.status.success(), "pvlib failed: {}", String::from_utf8_lossy(&output.stderr));
    let reference: Vec<(f64, f64)> = String::from_utf8(output.stdout)
        .unwrap()
        .lines()
        .map(|l| {
            let (a, e) = l.split_once(',').unwrap();
            (a.parse().unwrap(), e.parse().unwrap())
        })
        .collect();
    assert_eq!(reference.len(), cases.len());
    let (mut worst_el, mut worst_az, mut below, mut above) = (0.0f64, 0.0f64, 0, 0);
    for (((time, lat, lon), sun), (az, el)) in cases.iter().zip(&mine).zip(&reference) {
        let d_el = (sun.elevation_deg - el).abs();
        let d_az = ((sun.azimuth_deg - az + 540.0).rem_euclid(360.0) - 180.0).abs();
        assert!(d_el <= TOLERANCE_DEG, "{time} at {lat}, {lon}: elevation {} vs pvlib {el}", sun.elevation_deg);
        if *el < 89.5 {
            assert!(d_az <= TOLERANCE_DEG, "{time} at {lat}, {lon}: azimuth {} vs pvlib {az}", sun.azimuth_deg);
            worst_az = worst_az.max(d_az);
        }
        worst_el = worst_el.max(d_el);
        if *el < 0.0 { below += 1 } else { above += 1 }
    }
    // Day and night both came up, and the polar cases are what they are.
    assert!(below > 300 && above > 300, "{below} below the horizon, {above} above");
    assert!(mine[1000].elevation_deg > 0.0, "midnight sun at Longyearbyen: {:?}", mine[1000]);
    assert!(mine[1001].elevation_deg < 0.0, "polar night at Longyearbyen: {:?}", mine[1001]);
    println!("{} cases: worst elevation {worst_el:.2e} deg, worst azimuth {worst_az:.2e} deg", cases.len());
}
