//! Render the classic Cornell box from the library API:
//! `cargo run --release --example render_cornell` writes out/cornell.png.

use propsim::render::{self, IntegratorKind, RenderSettings};
use propsim::scene::{self, LoadOptions, World};

fn main() -> anyhow::Result<()> {
    let scene = scene::load("builtin:cornell_box_classic".as_ref(), &LoadOptions::default())?;
    let world = World::build(scene);
    let settings = RenderSettings { spp: 32, integrator: IntegratorKind::Path, ..RenderSettings::default() };
    let image = render::render_world(&world, &settings).map_err(anyhow::Error::msg)?;
    image.film.write("out/cornell.png".as_ref())?;
    println!("out/cornell.png: {:.2} M samples/s", image.samples as f64 / image.seconds / 1e6);
    Ok(())
}
