//! `docs/accuracy.md`: a table and a plot per knob, and why each default
//! is where it is.

use std::fmt::Write as _;
use std::path::Path;

use crate::sweep::Sweep;

/// Writes the report and its plots into `out` (`accuracy.md` and
/// `accuracy/<knob>.svg`).
pub fn write(out: &Path, sweeps: &[Sweep], header: &Header) -> anyhow::Result<()> {
    let plots = out.join("accuracy");
    std::fs::create_dir_all(&plots)?;
    let mut md = String::new();
    let _ = writeln!(md, "# What accuracy costs in time\n");
    let _ = writeln!(
        md,
        "Written by `make accuracy` (`cargo run --release -p relief-accuracy`); do not edit by hand.\n\n\
         - machine: {}\n- device: {}\n- run: {} ({:.1} minutes)\n",
        header.machine, header.device, header.date, header.minutes
    );
    let _ = writeln!(
        md,
        "Every knob that trades accuracy for time, swept against an independent reference: analytic surfaces, \
         f64 computations, GDAL and PROJ themselves, a reference render at the highest setting, ray-casts, \
         pvlib's SPA. Each table lists every setting measured; **bold** rows are on the Pareto front (no \
         other setting is at least as fast and as accurate), the default is marked. Each plot shows error \
         against time with the front drawn through.\n"
    );
    let _ = writeln!(md, "| knob | default | reference |\n|---|---|---|");
    for s in sweeps {
        let default = s.rows.iter().find(|r| r.default).map_or("—", |r| r.setting.as_str());
        let _ = writeln!(md, "| [{}](#{}) | {default} | {} |", s.knob, anchor(&s.knob), s.reference);
    }
    for s in sweeps {
        let stem = s.file_stem();
        crate::plot::write(s, &plots.join(format!("{stem}.svg")))?;
        let _ = writeln!(md, "\n## {}\n", s.knob);
        let _ = writeln!(md, "{}\n\n- reference: {}\n- error: {}\n- time: {}\n", s.case, s.reference, s.error, s.time);
        let extra: Vec<&str> =
            s.rows.first().map(|r| r.extra.iter().map(|(h, _)| h.as_str()).collect()).unwrap_or_default();
        let _ = write!(md, "| setting | time | error |");
        for h in &extra {
            let _ = write!(md, " {h} |");
        }
        let _ = writeln!(md, " |");
        let _ = writeln!(md, "|---|---|---|{}---|", "---|".repeat(extra.len()));
        let front = s.pareto();
        for (i, r) in s.rows.iter().enumerate() {
            let on = front.contains(&i);
            let b = if on { "**" } else { "" };
            let _ = write!(md, "| {b}{}{b} | {} | {} |", r.setting, number(r.time), number(r.error));
            for (_, v) in &r.extra {
                let _ = write!(md, " {v} |");
            }
            let mark = match (r.default, on) {
                (true, true) => "default, on the front",
                (true, false) => "default",
                (false, true) => "on the front",
                (false, false) => "",
            };
            let _ = writeln!(md, " {mark} |");
        }
        let _ = writeln!(md, "\n![{} error against time](accuracy/{stem}.svg)\n", s.knob);
        let _ = writeln!(md, "**Why the default.** {} {}", s.default_standing(), s.why_default);
    }
    std::fs::write(out.join("accuracy.md"), md)?;
    Ok(())
}

/// What the report says about the run.
pub struct Header {
    pub machine: String,
    pub device: String,
    pub date: String,
    pub minutes: f64,
}

/// A number with about three significant digits.
pub fn number(v: f64) -> String {
    if !v.is_finite() {
        return "—".into();
    }
    let a = v.abs();
    if a == 0.0 {
        "0".into()
    } else if a >= 100.0 {
        format!("{v:.0}")
    } else if a >= 10.0 {
        format!("{v:.1}")
    } else if a >= 1.0 {
        format!("{v:.2}")
    } else if a >= 0.001 {
        format!("{v:.4}")
    } else {
        format!("{v:.2e}")
    }
}

/// GitHub's heading anchor for `title`.
fn anchor(title: &str) -> String {
    title
        .to_lowercase()
        .chars()
        .filter_map(|c| match c {
            'a'..='z' | '0'..='9' | '-' | '_' => Some(c),
            ' ' => Some('-'),
            _ => None,
        })
        .collect()
}
