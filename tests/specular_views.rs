//! One room, two views: the acoustic image sources and the radio coherent receivers ask the
//! core's one specular-path engine, so they must find the same paths (count, orders and
//! lengths) between the same two points, the analytic spheres blocking both alike.

use glam::Vec3;
use propsim::acoustic::image_source::specular_arrivals;
use propsim::acoustic::simulate::surface_acoustics;
use propsim::acoustic::{AcousticSettings, ReceiverSpec, SourceSpec, simulate};
use propsim::core::specular::{Planes, specular_paths};
use propsim::core::{Accel, BuildQuality};
use propsim::rf::fresnel::C0;
use propsim::rf::propagation::SurfacePhysics;
use propsim::rf::receivers::coherent_paths;
use propsim::rf::{Antenna, Polarization, surface_permittivities};
use propsim::scene::{LoadOptions, World, load};

/// The showcase: the L-shaped room with a glass and a chrome sphere.
fn showcase() -> World {
    World::build(load("rooms/showcase/scene.toml".as_ref(), &LoadOptions::default()).unwrap())
}

const SOURCE: [f32; 3] = [7.0, 2.0, 1.5];
/// Line of sight, around the corner, and two points whose paths the spheres cut.
const RECEIVERS: [[f32; 3]; 4] = [[2.0, 2.0, 1.2], [2.0, 7.0, 1.2], [1.5, 1.0, 0.5], [2.0, 3.5, 0.4]];
const ORDER: u32 = 3;

#[test]
fn acoustic_and_radio_views_find_the_same_paths() {
    let world = showcase();
    assert_eq!(world.scene.spheres.len(), 2);
    let planes = Planes::of(&world.scene.mesh);
    let surfaces = surface_acoustics(&world).unwrap();
    let physics = SurfacePhysics {
        eta: surface_permittivities(&world, 3.5, false).unwrap(),
        slab_thickness_m: None,
        wavelength_m: C0 / 3.5e9,
        scattering: Vec::new(),
        table: None,
    };
    let antenna = Antenna::Isotropic { polarization: Polarization::Vertical };
    let no_spheres = Accel::build(&world.scene.mesh, Vec::new(), BuildQuality::default());
    let mut cut = 0;
    for r in RECEIVERS {
        let (s, r) = (Vec3::from(SOURCE), Vec3::from(r));
        let sound = specular_arrivals(&world.accel, &planes, &surfaces, &[0.0; 8], s, r, ORDER);
        let radio =
            coherent_paths(&world.accel, &planes, &physics, &antenna, s.as_dvec3(), r.as_dvec3(), ORDER);
        let mut a: Vec<(usize, f64)> = sound.iter().map(|p| (p.order, p.length_m)).collect();
        let mut b: Vec<(usize, f64)> =
            radio.path_orders.iter().copied().zip(radio.path_lengths_m.iter().copied()).collect();
        a.sort_by(|x, y| x.1.total_cmp(&y.1));
        b.sort_by(|x, y| x.1.total_cmp(&y.1));
        assert!(a.len() > 10, "{r}: {} paths", a.len());
        assert_eq!(a.len(), radio.paths);
        for (x, y) in a.iter().zip(&b) {
            assert_eq!(x.0, y.0);
            assert!((x.1 - y.1).abs() < 1e-12, "{r}: {} m against {} m", x.1, y.1);
        }
        assert_eq!(radio.line_of_sight, a[0].0 == 0);
        // Every path's legs clear both spheres.
        for p in specular_paths(&world.accel, &planes, s.as_dvec3(), r.as_dvec3(), ORDER) {
            for w in p.points().windows(2) {
                for sphere in &world.scene.spheres {
                    let (c, rad) = (sphere.center.as_dvec3(), f64::from(sphere.radius_m));
                    let t = ((c - w[0]).dot(w[1] - w[0]) / w[0].distance_squared(w[1])).clamp(0.0, 1.0);
                    assert!((w[0] + t * (w[1] - w[0])).distance(c) > rad, "{r}: a leg crosses a sphere");
                }
            }
        }
        cut += specular_paths(&no_spheres, &planes, s.as_dvec3(), r.as_dvec3(), ORDER).len() - a.len();
    }
    assert!(cut > 0, "the spheres must block some paths");
}

#[test]
fn the_acoustic_simulation_counts_the_radio_paths() {
    let world = showcase();
    let settings = AcousticSettings {
        rays: 1000,
        ism_order: ORDER,
        max_time_s: Some(0.5),
        ..AcousticSettings::default()
    };
    let sources =
        [SourceSpec { name: "S".into(), position: SOURCE, power_w: 1.0, directivity: Default::default() }];
    let receivers: Vec<ReceiverSpec> = RECEIVERS
        .iter()
        .enumerate()
        .map(|(i, &p)| ReceiverSpec {
            name: format!("R{i}"),
            position: p,
            radius_m: Some(0.1),
            listener: Default::default(),
            directivity: Default::default(),
        })
        .collect();
    let result = simulate(&world, &sources, &receivers, &settings, &|_| {}).unwrap();
    assert_eq!(result.ism_order, ORDER);
    let planes = Planes::of(&world.scene.mesh);
    let physics = SurfacePhysics {
        eta: surface_permittivities(&world, 3.5, false).unwrap(),
        slab_thickness_m: None,
        wavelength_m: C0 / 3.5e9,
        scattering: Vec::new(),
        table: None,
    };
    let antenna = Antenna::Isotropic { polarization: Polarization::Horizontal };
    for (pair, r) in result.pairs.iter().zip(RECEIVERS) {
        let tx = Vec3::from(SOURCE).as_dvec3();
        let radio =
            coherent_paths(&world.accel, &planes, &physics, &antenna, tx, Vec3::from(r).as_dvec3(), ORDER);
        assert_eq!(pair.specular_paths, radio.paths, "{}", pair.receiver);
    }
}
