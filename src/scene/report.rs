//! The scene report of `propsim info`: geometry, areas, volume, closedness, materials and
//! whether every source and receiver is inside the room.

use std::fmt::Write as _;

use glam::Vec3;
use serde::Serialize;

use super::World;

/// The report `propsim info` prints.
#[derive(Serialize, Debug)]
pub struct InfoReport {
    pub scene: String,
    pub obj: String,
    pub triangles: usize,
    pub vertices: usize,
    pub bounds_min_m: [f32; 3],
    pub bounds_max_m: [f32; 3],
    pub total_area_m2: f64,
    pub surfaces: Vec<SurfaceInfo>,
    pub closed: bool,
    pub open_edges: usize,
    pub over_shared_edges: usize,
    pub misoriented_edges: usize,
    pub consistently_oriented: bool,
    pub components: usize,
    pub closed_components: usize,
    pub air_volume_m3: Option<f64>,
    pub divergence_volume_m3: f64,
    pub points: Vec<PointInfo>,
    pub warnings: Vec<String>,
}

#[derive(Serialize, Debug)]
pub struct SurfaceInfo {
    pub name: String,
    pub material: Option<String>,
    pub area_m2: f64,
    pub acoustic: bool,
    pub radio: Option<String>,
}

#[derive(Serialize, Debug)]
pub struct PointInfo {
    pub kind: String,
    pub name: String,
    pub position_m: [f32; 3],
    /// `None` when the scene encloses no air.
    pub inside: Option<bool>,
}

/// Builds the report for a loaded world.
pub fn report(world: &World, extra_points: &[[f32; 3]]) -> InfoReport {
    let s = &world.scene;
    let r = &world.report;
    let (lo, hi) = s.mesh.bounds().unwrap_or((Vec3::ZERO, Vec3::ZERO));
    let surfaces = s
        .surfaces
        .iter()
        .enumerate()
        .map(|(i, surf)| SurfaceInfo {
            name: surf.name.clone(),
            material: surf.material.as_ref().map(|m| m.name.clone()),
            area_m2: r.area_by_surface_m2.get(i).copied().unwrap_or(0.0),
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
        bounds_min_m: lo.to_array(),
        bounds_max_m: hi.to_array(),
        total_area_m2: r.total_area_m2,
        surfaces,
        closed: r.is_closed(),
        open_edges: r.open_edges,
        over_shared_edges: r.over_shared_edges,
        misoriented_edges: r.misoriented_edges,
        consistently_oriented: r.is_consistently_oriented(),
        components: r.components.len(),
        closed_components: r.components.iter().filter(|c| c.closed).count(),
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
    let _ = writeln!(o, "area:       {:.3} m^2", r.total_area_m2);
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
