//! A radio coverage map of the street canyon in a few lines:
//! `cargo run --release --example rf_coverage`.

use propsim::rf::output::{summary, write_coverage_csv};
use propsim::rf::{RfConfig, RfOptions, simulate};
use propsim::scene::{LoadOptions, World, load};

fn main() -> anyhow::Result<()> {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/rooms/street_canyon/scene.toml");
    let world = World::build(load(path.as_ref(), &LoadOptions::default())?);
    // The scene's transmitter and grid, with 10^6 rays and 2 m cells.
    let overrides = RfOptions { rays: Some(1_000_000), cell_m: Some(2.0), ..RfOptions::default() };
    let config = RfConfig::from_scene(&world, &overrides).map_err(anyhow::Error::msg)?;
    let result = simulate(&world, &config, &|_| {})?;
    let out = std::env::temp_dir().join("propsim_rf_example.csv");
    write_coverage_csv(&out, &config, &result)?;
    let s = summary(path, &config, &result, vec![out.display().to_string()]);
    println!(
        "{} of {} cells reached, median path gain {:?} dB",
        s.map.reached_cells, s.map.cells, s.map.median_path_gain_db
    );
    for r in &s.receivers {
        println!("{}: {} exact paths, coherent path gain {:?} dB", r.name, r.paths, r.coherent_path_gain_db);
    }
    println!("wrote {}", out.display());
    Ok(())
}
