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
    /// Extra materials file(s).
    #[arg(long = "materials")]
    pub materials: Vec<PathBuf>,
    #[command(flatten)]
    pub model: super::ModelArgs,
    /// Extra points to test for inside/outside, as X,Y,Z.
    #[arg(long = "point", value_parser = super::parse_point, allow_hyphen_values = true)]
    pub points: Vec<[f32; 3]>,
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: &InfoArgs) -> anyhow::Result<()> {
    let options = super::load_options(&args.materials, &args.model);
    let scene = scene::load(&args.scene, &options)?;
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
        say!("{}", serde_json::to_string_pretty(&r)?);
    } else {
        crate::out!("{}", format_report(&r));
    }
    Ok(())
}
