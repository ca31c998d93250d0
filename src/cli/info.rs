//! `propsim info SCENE`: what the scene contains and whether it is fit for simulation.

use std::path::PathBuf;

use clap::Args;

use crate::scene::report::{format_report, report};
use crate::scene::{self, World};

#[derive(Args, Debug)]
pub struct InfoArgs {
    /// Scene file (.toml), bare OBJ, or builtin:NAME.
    #[arg(default_value = super::DEFAULT_SCENE)]
    pub scene: PathBuf,
    #[command(flatten)]
    pub load: crate::scene::LoadOptions,
    /// Extra points to test for inside/outside, as X,Y,Z.
    #[arg(long = "point", value_parser = super::parse_point, allow_hyphen_values = true)]
    pub points: Vec<[f32; 3]>,
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: &InfoArgs) -> anyhow::Result<()> {
    let scene = scene::load(&args.scene, &args.load)?;
    for w in &scene.warnings {
        tell!("warning: {w}");
    }
    let world = World::build(scene);
    let r = report(&world, &args.points);
    if r.over_shared_edges > 0 {
        tell!(
            "warning: {}: {} edges are shared by more than two triangles (an internal sheet or T-join)",
            r.obj,
            r.over_shared_edges
        );
    }
    if args.json {
        say!("{}", crate::io::json::to_pretty(&r)?);
    } else {
        crate::out!("{}", format_report(&r));
    }
    Ok(())
}
