//! Writes the demo scene: real terrain (the SRTM crop committed under
//! `examples/data`, or the DEM given), its hypsometric tint shaded by the
//! relief, a town, a forest, a lake, and a manifest that shows them.
//!
//! relief-demo-scene OUT_DIR [DEM]

use std::path::PathBuf;

use anyhow::Context;

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let out = PathBuf::from(args.next().context("usage: relief-demo-scene OUT_DIR [DEM]")?);
    let dem = args.next().map_or_else(|| PathBuf::from(relief_examples::ALPS_DEM), PathBuf::from);
    let manifest = relief_examples::write_alps_demo_scene(&out, &dem)?;
    #[expect(clippy::print_stdout, reason = "tells the caller where the scene is")]
    {
        println!("{}", manifest.display());
    }
    Ok(())
}
