//! The scene report of `propsim info`: geometry, areas, volume, closedness, materials and
//! whether every source and receiver is inside the room.

use std::fmt::Write as _;

use glam::Vec3;
use serde::Serialize;

use super::World;

/// The report `propsim info` prints.
#[derive(Serialize, Debug)]
pub struct InfoReport {
    /// Scene file path.
    pub scene: String,
    /// OBJ file path.
    pub obj: String,
    /// Number of triangles.
    pub triangles: usize,
    /// Number of distinct vertices.
    pub vertices: usize,
    /// Placed copies of meshes (`[[instances]]`).
    pub instances: usize,
    /// Triangles stored once: the scene's own and one copy of each instanced mesh
    /// (`triangles` counts every copy).
    pub unique_triangles: usize,
    /// Lower corner of the bounding box, metres.
    pub bounds_min_m: [f32; 3],
    /// Upper corner of the bounding box, metres.
    pub bounds_max_m: [f32; 3],
    /// Total surface area of the mesh, m^2.
    pub total_area_m2: f64,
    /// Surface area of the analytic spheres, m^2 (4 pi r^2 each), not in `total_area_m2`.
    pub sphere_area_m2: f64,
    /// Each surface, its material and area.
    pub surfaces: Vec<SurfaceInfo>,
    /// Whether every edge is shared by exactly two triangles.
    pub closed: bool,
    /// Edges used by one triangle only.
    pub open_edges: usize,
    /// Edges shared by more than two triangles.
    pub over_shared_edges: usize,
    /// Edges whose two triangles have flipped orientations.
    pub misoriented_edges: usize,
    /// Whether neighbouring triangles are wound alike.
    pub consistently_oriented: bool,
    /// Connected components of the mesh.
    pub components: usize,
    /// Closed connected components.
    pub closed_components: usize,
    /// Volume of air, m^3; `None` when the scene encloses no air.
    pub air_volume_m3: Option<f64>,
    /// Sum of signed tetrahedron volumes over all triangles (divergence theorem), m^3.
    pub divergence_volume_m3: f64,
    /// Sources, transmitters and receivers, and whether each is inside.
    pub points: Vec<PointInfo>,
    /// Warnings from loading the scene.
    pub warnings: Vec<String>,
}

/// One surface's line in the report.
#[derive(Serialize, Debug)]
pub struct SurfaceInfo {
    /// Surface name.
    pub name: String,
    /// Material name, `None` when only the MTL file gives one.
    pub material: Option<String>,
    /// Area, m^2.
    pub area_m2: f64,
    /// Whether the material has acoustic data.
    pub acoustic: bool,
    /// The material's radio data, in words.
    pub radio: Option<String>,
}

/// One point of the scene (source, receiver, transmitter) in the report.
#[derive(Serialize, Debug)]
pub struct PointInfo {
    /// What the point is ("acoustic source", "transmitter", ...).
    pub kind: String,
    /// Name.
    pub name: String,
    /// Position, metres.
    pub position_m: [f32; 3],
    /// `None` when the scene encloses no air.
    pub inside: Option<bool>,
}

/// Builds the report for a loaded world.
pub fn report(world: &World, extra_points: &[[f32; 3]]) -> InfoReport {
    let s = &world.scene;
    let r = &world.report;
    let (lo, hi) = s.mesh.bounds().unwrap_or((Vec3::ZERO, Vec3::ZERO));
    let (ilo, ihi) = world.accel.instances.bounds();
    let (lo, hi) = if ilo.x <= ihi.x { (lo.min(ilo), hi.max(ihi)) } else { (lo, hi) };
    let surfaces = s
        .surfaces
        .iter()
        .enumerate()
        .map(|(i, surf)| SurfaceInfo {
            name: surf.name.clone(),
            material: surf.material.as_ref().map(|m| m.name.clone()),
            area_m2: r.area_by_surface_m2.get(i).copied().unwrap_or(0.0)
                + s.spheres
                    .iter()
                    .filter(|sp| sp.surface as usize == i)
                    .map(|sp| 4.0 * std::f64::consts::PI * f64::from(sp.radius_m).powi(2))
                    .sum::<f64>()
                + s.shapes
                    .iter()
                    .filter(|(_, id)| *id as usize == i)
                    .filter_map(|(sh, _)| sh.area_m2())
                    .sum::<f64>(),
            acoustic: surf.material.as_ref().is_some_and(|m| m.acoustic.is_some()),
            radio: surf.material.as_ref().and_then(|m| m.radio.as_ref()).map(|r| r.to_string()),
        })
        .collect();
    let mut points = Vec::new();
    let mut add = |kind: &str, name: &str, p: [f32; 3]| {
        points.push(PointInfo {
            kind: kind.into(),
            name: name.into(),
            position_m: p,
            inside: world.is_inside(Vec3::from(p)),
        });
    };
    if let Some(a) = &s.desc.acoustic {
        a.sources.iter().for_each(|p| add("acoustic source", &p.name, p.position));
        a.receivers.iter().for_each(|p| add("acoustic receiver", &p.name, p.position));
    }
    if let Some(rf) = &s.desc.rf {
        rf.transmitters.iter().for_each(|t| add("transmitter", &t.name, t.position));
        rf.receivers.iter().for_each(|p| add("radio receiver", &p.name, p.position));
    }
    for (i, p) in extra_points.iter().enumerate() {
        add("point", &format!("#{}", i + 1), *p);
    }
    InfoReport {
        scene: s.path.display().to_string(),
        obj: s.obj_path.display().to_string(),
        triangles: r.triangles,
        vertices: r.distinct_vertices,
        instances: r.instances,
        unique_triangles: if r.instances > 0 { r.unique_triangles } else { r.triangles },
        bounds_min_m: lo.to_array(),
        bounds_max_m: hi.to_array(),
        total_area_m2: r.total_area_m2,
        sphere_area_m2: s
            .spheres
            .iter()
            .map(|sp| 4.0 * std::f64::consts::PI * f64::from(sp.radius_m).powi(2))
            .sum::<f64>()
            + s.shapes.iter().filter_map(|(sh, _)| sh.area_m2()).sum::<f64>(),
        surfaces,
        closed: r.is_closed(),
        open_edges: r.open_edges,
        over_shared_edges: r.over_shared_edges,
        misoriented_edges: r.misoriented_edges,
        consistently_oriented: r.is_consistently_oriented(),
        components: r.components.len() + r.instanced_components,
        closed_components: r.components.iter().filter(|c| c.closed).count() + r.instanced_closed_components,
        air_volume_m3: r.air_volume_m3,
        divergence_volume_m3: r.divergence_volume_m3,
        points,
        warnings: s.warnings.clone(),
    }
}

/// Human-readable text of a report.
pub fn format_report(r: &InfoReport) -> String {
    let mut o = String::new();
    let v3 = |v: [f32; 3]| format!("({:.3}, {:.3}, {:.3})", v[0], v[1], v[2]);
    let _ = writeln!(o, "scene:      {}", r.scene);
    let _ = writeln!(o, "geometry:   {} ({} triangles, {} vertices)", r.obj, r.triangles, r.vertices);
    if r.instances > 0 {
        let _ = writeln!(
            o,
            "instances:  {} copies: {} instanced triangles, {} unique",
            r.instances, r.triangles, r.unique_triangles
        );
    }
    let _ = writeln!(o, "bounds:     {} to {} m", v3(r.bounds_min_m), v3(r.bounds_max_m));
    let _ = writeln!(o, "surfaces:");
    for s in &r.surfaces {
        let mat = match &s.material {
            Some(m) if m == &s.name => m.clone(),
            Some(m) => format!("-> {m}"),
            None => "(MTL only)".into(),
        };
        let mut props = Vec::new();
        if s.acoustic {
            props.push("acoustic".to_string());
        }
        if let Some(radio) = &s.radio {
            props.push(format!("radio {radio}"));
        }
        let _ = writeln!(o, "  {:<28} {:<24} {:>10.3} m^2  {}", s.name, mat, s.area_m2, props.join(", "));
    }
    if r.sphere_area_m2 > 0.0 {
        let _ = writeln!(
            o,
            "area:       {:.3} m^2 of mesh, {:.3} m^2 of spheres and shapes",
            r.total_area_m2, r.sphere_area_m2
        );
    } else {
        let _ = writeln!(o, "area:       {:.3} m^2", r.total_area_m2);
    }
    let _ = writeln!(
        o,
        "closed:     {} ({} open edges, {} over-shared edges)",
        if r.closed { "yes" } else { "no" },
        r.open_edges,
        r.over_shared_edges
    );
    let _ = writeln!(
        o,
        "oriented:   {} ({} edges with flipped neighbours)",
        if r.consistently_oriented { "consistently" } else { "NOT consistently" },
        r.misoriented_edges
    );
    let _ = writeln!(o, "components: {} ({} closed)", r.components, r.closed_components);
    match r.air_volume_m3 {
        Some(v) => {
            let _ = writeln!(
                o,
                "volume:     {v:.3} m^3 of air (divergence sum {:.3} m^3)",
                r.divergence_volume_m3
            );
        }
        None => {
            let _ = writeln!(
                o,
                "volume:     n/a, the scene encloses no air (divergence sum {:.3} m^3)",
                r.divergence_volume_m3
            );
        }
    }
    for p in &r.points {
        let _ = writeln!(
            o,
            "{:<18} {:<10} {}  {}",
            p.kind,
            p.name,
            v3(p.position_m),
            match p.inside {
                Some(true) => "inside",
                Some(false) => "OUTSIDE",
                None => "(open scene: no inside)",
            }
        );
    }
    o
}
