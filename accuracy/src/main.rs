//! `make accuracy`: for every knob that trades accuracy for time, a sweep
//! against an independent reference, written to `docs/accuracy.md` with a
//! plot per knob. Takes under 30 minutes on a 2-core machine with
//! lavapipe; CI builds it and never runs it.

#![expect(clippy::print_stdout, clippy::print_stderr, reason = "a report tool tells its progress")]

mod knobs;
mod plot;
mod report;
mod sweep;

use std::path::PathBuf;
use std::time::Instant;

use clap::Parser;

#[derive(Parser)]
#[command(name = "relief-accuracy", about = "sweep every accuracy knob against its reference into docs/accuracy.md")]
struct Args {
    /// Where accuracy.md and accuracy/*.svg go.
    #[arg(long, default_value = "docs")]
    out: PathBuf,
    /// Only these knobs (comma-separated names from --list); the report then
    /// holds only them.
    #[arg(long, value_delimiter = ',')]
    only: Vec<String>,
    /// List the knobs and exit.
    #[arg(long)]
    list: bool,
}

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    if args.list {
        for (name, _) in knobs::ALL {
            println!("{name}");
        }
        return Ok(());
    }
    if let Some(unknown) = args.only.iter().find(|o| !knobs::ALL.iter().any(|(n, _)| n == o)) {
        let names: Vec<&str> = knobs::ALL.iter().map(|(n, _)| *n).collect();
        anyhow::bail!("no knob '{unknown}' (knobs: {})", names.join(", "));
    }
    let started = Instant::now();
    let context = knobs::Context::new()?;
    let mut sweeps = Vec::new();
    for (name, run) in knobs::ALL {
        if !args.only.is_empty() && !args.only.iter().any(|o| o == name) {
            continue;
        }
        let at = Instant::now();
        eprintln!("accuracy: {name}...");
        let mut found = run(&context)?;
        eprintln!("accuracy: {name}: {} sweeps in {:.0} s", found.len(), at.elapsed().as_secs_f64());
        sweeps.append(&mut found);
    }
    let header = report::Header {
        machine: relief_tests::machine(),
        device: context.gpu.description.clone(),
        date: chrono::Utc::now().format("%Y-%m-%d %H:%M UTC").to_string(),
        minutes: started.elapsed().as_secs_f64() / 60.0,
    };
    report::write(&args.out, &sweeps, &header)?;
    println!("wrote {} ({} knobs)", args.out.join("accuracy.md").display(), sweeps.len());
    Ok(())
}
