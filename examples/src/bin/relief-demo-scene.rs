//! Writes the demo scene: a synthetic mountain range (DEM), an "orthophoto"
//! tinted by height, and a manifest that drapes it and shades the relief.
//!
//! relief-demo-scene OUT_DIR

use std::path::PathBuf;

use anyhow::Context;

fn main() -> anyhow::Result<()> {
    let out = PathBuf::from(std::env::args().nth(1).context("usage: relief-demo-scene OUT_DIR")?);
    let manifest = relief_examples::write_demo_scene(&out)?;
    #[expect(clippy::print_stdout, reason = "tells the caller where the scene is")]
    {
        println!("{}", manifest.display());
    }
    Ok(())
}
