//! Signed distance fields: sphere-traced hits against closed forms (the analytic sphere,
//! grazing rays built from a surface point and its tangent plane), the Lipschitz bounds of the
//! smooth combinations, a render of `rooms/sdf` bit for bit on 1 and 2 threads with every
//! integrator seeing the fields, and one error line per bad `[[sdfs]]` entry.

mod common;

use common::render::go;
use glam::{Affine3A, Quat, Vec2, Vec3};
use propsim::core::Ray;
use propsim::core::rng::{stream, uniform};
use propsim::core::sampling::uniform_sphere;
use propsim::core::sdf::{ACCURACY_RELATIVE, Sdf, SdfNode, SdfShape, smooth_max, smooth_min};
use propsim::render::{Film, IntegratorKind, RenderScene, RenderSettings};
use propsim::scene::{self, LoadOptions, World};

fn node(shape: SdfShape, m: Affine3A) -> SdfNode {
    SdfNode::new(shape, m).expect("a similarity")
}

fn placement() -> Affine3A {
    Affine3A::from_scale_rotation_translation(
        Vec3::splat(1.7),
        Quat::from_axis_angle(Vec3::new(1.0, 2.0, 3.0).normalize(), 0.8),
        Vec3::new(0.3, -0.2, 0.5),
    )
}

/// The SDF sphere (radius 0.6, placed by a similarity of scale 1.7, so a world radius of
/// 1.02) against the closed-form ray-sphere intersection on 10^5 random rays: every ray that
/// passes more than `eps` inside the silhouette hits, within `eps` of the true surface and
/// within `eps / cos` of the true distance; every ray that passes more than `eps` outside
/// misses; and rays starting inside find the exit.
#[test]
fn sdf_sphere_matches_the_analytic_sphere_within_the_stated_accuracy() {
    let m = placement();
    let sdf = Sdf::new(node(SdfShape::Sphere { radius_m: 0.6 }, m), 512);
    let c: Vec3 = m.translation.into();
    let radius = 0.6f64 * 1.7;
    let (lo, hi) = sdf.bounds();
    let (mut hits, mut band, mut worst_point, mut worst_t) = (0, 0, 0.0f64, 0.0f64);
    for k in 0..100_000u64 {
        let mut r = stream(7, 0, k);
        let target = lo + (hi - lo) * Vec3::new(uniform(&mut r), uniform(&mut r), uniform(&mut r));
        let inside = k % 10 == 0;
        let o = if inside {
            // A point inside the sphere, a random direction.
            let u = uniform_sphere(Vec2::new(uniform(&mut r), uniform(&mut r)));
            c + u * (0.9 * radius as f32) * uniform(&mut r)
        } else {
            target + 8.0 * uniform_sphere(Vec2::new(uniform(&mut r), uniform(&mut r)))
        };
        let dir = if inside {
            uniform_sphere(Vec2::new(uniform(&mut r), uniform(&mut r)))
        } else {
            (target - o).normalize()
        };
        let ray = Ray::new(o, dir);
        // Closed form in f64: |o + t d - c|^2 = R^2.
        let (oc, d) = ((o - c).as_dvec3(), dir.as_dvec3());
        let b = oc.dot(d);
        let miss_m = (oc - b * d).length() - radius; // > 0: the line passes outside
        let disc = b * b - (oc.length_squared() - radius * radius);
        let t_true = if disc >= 0.0 {
            let s = disc.sqrt();
            if -b - s > 0.0 {
                Some(-b - s)
            } else if -b + s > 0.0 {
                Some(-b + s)
            } else {
                None
            }
        } else {
            None
        };
        let got = sdf.intersect(&ray);
        let eps = f64::from(ACCURACY_RELATIVE) * (oc.length() + radius + 0.5 * f64::from((hi - lo).length()));
        match (t_true, got) {
            (Some(tt), Some((t, n))) => {
                hits += 1;
                let p = ray.at(t);
                let off = ((p - c).length() as f64 - radius).abs();
                assert!(off <= eps, "ray {k}: hit point {off} m off the sphere (eps {eps})");
                worst_point = worst_point.max(off / eps);
                let cos = (p - c).normalize().dot(dir).abs().max(1e-3) as f64;
                assert!((f64::from(t) - tt).abs() <= eps / cos + 1e-6, "ray {k}: t {t} vs {tt}");
                worst_t = worst_t.max((f64::from(t) - tt).abs() * cos / eps);
                assert!(n.dot((p - c).normalize()) > 0.999, "ray {k}: normal {n}");
            }
            (None, None) => {}
            _ if miss_m.abs() <= 2.0 * eps => band += 1,
            (t, g) => panic!("ray {k}: analytic {t:?}, traced {g:?}, passes {miss_m} m from the surface"),
        }
    }
    eprintln!(
        "hits {hits}, silhouette band {band}, worst point error {worst_point:.3} eps, worst t {worst_t:.3} eps/cos"
    );
    assert!(hits > 20_000, "{hits}");
    assert!(band < 100, "{band} rays within eps of the silhouette");
}

/// Rays grazing the surface: from a surface point `q` with normal `n`, a tangent direction
/// `d`, the line through `q - delta n` (inside the solid) must hit before reaching that point
/// (it starts outside, so it crosses the surface); on the box, a convex solid, the line
/// through `q + delta n` (delta above the accuracy) must miss. `delta` goes down to 10^-6 of
/// the size, far inside the accuracy band.
#[test]
fn no_grazing_hit_is_missed_on_a_box_and_a_torus() {
    let m = placement();
    let half = Vec3::new(0.5, 0.3, 0.2);
    let boxed = Sdf::new(node(SdfShape::Box { half_m: half }, m), 512);
    let (major, minor) = (0.5f32, 0.15f32);
    let torus = Sdf::new(node(SdfShape::Torus { major_m: major, minor_m: minor }, m), 512);
    let s = 1.7f32;
    let (mut tested, mut missed_outside) = (0, 0);
    for k in 0..20_000u64 {
        let mut r = stream(11, 0, k);
        let delta_rel = [1e-2f32, 1e-3, 1e-4, 1e-5, 1e-6][(k % 5) as usize];
        // A surface point and normal in the canonical frame.
        let (which, q, n) = if k % 2 == 0 {
            let axis = (uniform(&mut r) * 3.0) as usize % 3;
            let side = if uniform(&mut r) < 0.5 { -1.0 } else { 1.0 };
            let mut q = (Vec3::new(uniform(&mut r), uniform(&mut r), uniform(&mut r)) * 2.0 - 1.0) * half;
            q[axis] = side * half[axis];
            let mut n = Vec3::ZERO;
            n[axis] = side;
            (&boxed, q, n)
        } else {
            let (u, v) = (uniform(&mut r) * std::f32::consts::TAU, uniform(&mut r) * std::f32::consts::TAU);
            let ring = Vec3::new(u.cos(), u.sin(), 0.0);
            let n = ring * v.cos() + Vec3::Z * v.sin();
            (&torus, ring * major + n * minor, n)
        };
        // A random tangent direction.
        let a = uniform_sphere(Vec2::new(uniform(&mut r), uniform(&mut r)));
        let d = (a - n * a.dot(n)).normalize();
        let (qw, nw, dw) =
            (m.transform_point3(q), m.transform_vector3(n).normalize(), m.transform_vector3(d).normalize());
        let delta = delta_rel * s;
        let back = 4.0 * s;
        let inner = qw - delta * nw;
        let ray = Ray::new(inner - back * dw, dw);
        let hit = which.intersect(&ray);
        assert!(
            hit.is_some_and(|(t, _)| t <= back * (1.0 + 1e-5)),
            "ray {k}: grazing {delta} m inside, hit {hit:?} (must be at most {back})"
        );
        tested += 1;
        if k % 2 == 0 {
            // Outside a convex solid by 4 eps: a miss (unless the tangent line runs along a
            // face, which a random tangent does not).
            let outer = qw + 4.0 * which.accuracy_m(back + 1.0) * nw;
            let ray = Ray::new(outer - back * dw, dw);
            if which.intersect(&ray).is_some() {
                missed_outside += 1;
            }
        }
    }
    assert_eq!(missed_outside, 0, "rays passing outside the box reported as hits");
    assert_eq!(tested, 20_000);
}

/// The smooth union and subtraction keep Lipschitz constant 1 (checked on random pairs of
/// points: `|f(x) - f(y)| <= |x - y|`), and stay within `k / 4` of the sharp min and max.
#[test]
fn smooth_combinations_keep_the_lipschitz_bound() {
    let a = node(SdfShape::Sphere { radius_m: 0.5 }, Affine3A::from_translation(Vec3::new(-0.3, 0.0, 0.0)));
    let b = node(
        SdfShape::RoundBox { half_m: Vec3::new(0.3, 0.4, 0.2), rounding_m: 0.05 },
        Affine3A::from_rotation_z(0.4) * Affine3A::from_translation(Vec3::new(0.3, 0.1, 0.0)),
    );
    let c = node(
        SdfShape::Capsule { a: Vec3::ZERO, b: Vec3::new(0.0, 0.0, 0.6), radius_m: 0.1 },
        Affine3A::IDENTITY,
    );
    let k = 0.2;
    for shape in [
        SdfShape::SmoothUnion { children: vec![a.clone(), b.clone(), c.clone()], blend_m: k },
        SdfShape::SmoothSubtraction { children: vec![b.clone(), a.clone(), c.clone()], blend_m: k },
    ] {
        let f = node(shape, Affine3A::IDENTITY);
        assert_eq!(f.lipschitz(), 1.0);
        let mut worst = 0.0f32;
        for i in 0..200_000u64 {
            let mut r = stream(13, 0, i);
            let x = (Vec3::new(uniform(&mut r), uniform(&mut r), uniform(&mut r)) * 2.0 - 1.0) * 1.2;
            let y = x + 0.05 * uniform(&mut r) * uniform_sphere(Vec2::new(uniform(&mut r), uniform(&mut r)));
            let dist = (x - y).length();
            if dist > 1e-4 {
                worst = worst.max((f.distance(x) - f.distance(y)).abs() / dist);
            }
        }
        assert!(worst <= 1.0 + 1e-2, "difference quotient {worst}");
        assert!(worst > 0.9, "difference quotient {worst}: the test does not probe");
    }
    // The blend stays within k / 4 of the sharp operation, and vanishes beyond |a - b| = k.
    for i in 0..10_000u64 {
        let mut r = stream(17, 0, i);
        let (x, y) = (uniform(&mut r) * 2.0 - 1.0, uniform(&mut r) * 2.0 - 1.0);
        let s = smooth_min(x, y, k);
        assert!(s <= x.min(y) && s >= x.min(y) - 0.25 * k, "{x} {y} {s}");
        assert!(smooth_max(x, y, k) >= x.max(y));
        if (x - y).abs() >= k {
            assert_eq!(s, x.min(y));
        }
    }
}

fn sdf_world() -> World {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/rooms/sdf/scene.toml");
    World::build(scene::load(path.as_ref(), &LoadOptions::default()).expect("rooms/sdf loads"))
}

/// `rooms/sdf` renders bit for bit the same on 1 and 2 threads with every integrator that
/// takes it (all but radiosity), and the camera's rays meet all four fields.
#[test]
fn the_sdf_room_renders_the_same_on_one_and_two_threads() {
    let world = sdf_world();
    assert_eq!(world.accel.sdfs.sdfs.len(), 4);
    let scene = RenderScene::new(&world);
    let cam = propsim::render::scene_camera(&world, 48.0 / 36.0).unwrap();
    let bits = |f: &Film| f.pixels.iter().flat_map(|p| p.to_array().map(f32::to_bits)).collect::<Vec<u32>>();
    for integrator in [
        IntegratorKind::Raycast,
        IntegratorKind::Whitted,
        IntegratorKind::Distributed,
        IntegratorKind::Path,
        IntegratorKind::Light,
        IntegratorKind::Bdpt,
        IntegratorKind::Sppm,
    ] {
        let s = RenderSettings {
            width: 48,
            height: 36,
            spp: 2,
            max_depth: 5,
            integrator,
            seed: 5,
            ..RenderSettings::default()
        };
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| go(&scene, &cam, &s))
        };
        let one = run(1);
        assert!(one.pixels.iter().all(|p| p.is_finite()), "{integrator:?}");
        assert!(one.mean().max_element() > 0.0, "{integrator:?}");
        assert_eq!(bits(&one), bits(&run(2)), "{integrator:?}");
    }
    // Radiosity patches mesh triangles only: it refuses the fields in one line.
    let refused = propsim::render::radiosity::supported(&scene).expect_err("radiosity refuses fields");
    assert!(refused.contains("signed distance fields") && !refused.contains('\n'), "{refused}");
    // Primary visibility: the camera's rays over the image meet every field.
    let mut kinds = std::collections::BTreeMap::new();
    for y in 0..36 {
        for x in 0..48 {
            let ray = cam.ray(Vec2::new((x as f32 + 0.5) / 48.0, (y as f32 + 0.5) / 36.0), Vec2::splat(0.5));
            if let Some(h) = scene.intersect(&ray)
                && h.kind == propsim::core::PrimitiveKind::Sdf
            {
                kinds.insert(h.primitive, ray);
            }
        }
    }
    assert_eq!(kinds.len(), 4, "fields seen by the camera: {kinds:?}");
    // The launchers' queries (acoustic and radio rays, batch and single) and the shadow-ray
    // query see them too, on a camera ray that met each field.
    let rays: Vec<Ray> = kinds.values().copied().collect();
    let mut batch = vec![None; rays.len()];
    world.accel.closest_hits_into(&rays, &mut batch);
    for (i, (ray, b)) in rays.iter().zip(&batch).enumerate() {
        let h = world.accel.closest_hit(ray).expect("a hit");
        assert_eq!(Some(h), *b, "field {i}: batch and single queries agree");
        assert_eq!(h.kind, propsim::core::PrimitiveKind::Sdf, "field {i}: {h:?}");
        let before = Ray::segment(ray.origin, ray.dir, 0.99 * h.t);
        let through = Ray::segment(ray.origin, ray.dir, 1.01 * h.t);
        assert!(!world.accel.occluded(&before) && world.accel.occluded(&through), "field {i}");
    }
}

/// Writes `body` after a minimal room as `scene.toml` in a fresh directory; the load error.
fn load_error(name: &str, body: &str) -> (String, String) {
    let dir = std::env::temp_dir().join(format!("propsim_sdf_{name}_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("room.obj"), common::box_obj([2.0, 2.0, 2.0])).unwrap();
    let path = dir.join("scene.toml");
    std::fs::write(&path, format!("obj = \"room.obj\"\n[surfaces]\ntest_wall = \"concrete_rough\"\n{body}"))
        .unwrap();
    let err = match scene::load(&path, &LoadOptions::default()) {
        Ok(_) => panic!("{name}: loads"),
        Err(e) => e.to_string(),
    };
    (err, path.display().to_string())
}

/// Each bad entry fails with one line naming the file, the entry and the problem; the CLI
/// prints it as its one error line.
#[test]
fn bad_sdf_entries_fail_with_one_clear_line() {
    let cases = [
        ("unknown", "[[sdfs]]\nkind = \"blob\"\nmaterial = \"concrete_rough\"\n", "unknown kind \"blob\""),
        (
            "radius",
            "[[sdfs]]\nkind = \"sphere\"\nmaterial = \"concrete_rough\"\nradius_m = -1.0\n",
            "radius_m = -1",
        ),
        (
            "key",
            "[[sdfs]]\nkind = \"sphere\"\nmaterial = \"concrete_rough\"\nradius_m = 1.0\nsize_m = [1.0, 1.0, 1.0]\n",
            "size_m is not a key of sphere",
        ),
        ("nomaterial", "[[sdfs]]\nkind = \"sphere\"\nradius_m = 0.5\n", "needs a material"),
        (
            "rounding",
            "[[sdfs]]\nkind = \"rounded_box\"\nmaterial = \"concrete_rough\"\nsize_m = [0.2, 0.2, 0.2]\nrounding_m = 0.5\n",
            "rounding_m = 0.5",
        ),
        (
            "onechild",
            "[[sdfs]]\nkind = \"smooth_union\"\nmaterial = \"concrete_rough\"\n[[sdfs.children]]\nkind = \"sphere\"\nradius_m = 0.5\n",
            "at least two children",
        ),
        (
            "child",
            "[[sdfs]]\nkind = \"smooth_union\"\nmaterial = \"concrete_rough\"\n[[sdfs.children]]\nkind = \"sphere\"\nradius_m = 0.5\n[[sdfs.children]]\nkind = \"torus\"\nmajor_radius_m = 0.5\n",
            "child #2 (torus): needs minor_radius_m",
        ),
        (
            "power",
            "[[sdfs]]\nkind = \"mandelbulb\"\nmaterial = \"concrete_rough\"\npower = 40.0\n",
            "power = 40",
        ),
        (
            "steps",
            "[[sdfs]]\nkind = \"mandelbulb\"\nmaterial = \"concrete_rough\"\nscale = 0.5\ntranslate = [1.0, 1.0, 1.0]\nmax_steps = 3\n",
            "does not converge",
        ),
        (
            "capsule",
            "[[sdfs]]\nkind = \"capsule\"\nmaterial = \"concrete_rough\"\nfrom = [0.0, 0.0, 0.0]\nto = [0.0, 0.0, 0.0]\nradius_m = 0.1\n",
            "distinct",
        ),
        (
            "material",
            "[[sdfs]]\nkind = \"sphere\"\nmaterial = \"concrete_ruff\"\nradius_m = 0.5\n",
            "unknown material",
        ),
    ];
    for (name, body, needle) in cases {
        let (err, path) = load_error(name, body);
        assert!(!err.contains('\n'), "{name}: {err}");
        assert!(err.contains(&path) && err.contains("sdf #1"), "{name}: {err}");
        assert!(err.contains(needle), "{name}: \"{needle}\" not in {err}");
    }
    let (_, path) = load_error("cli", "[[sdfs]]\nkind = \"blob\"\nmaterial = \"concrete_rough\"\n");
    common::assert_clean_error(&["info", &path], &["sdf #1 (blob)", "unknown kind"]);
}
