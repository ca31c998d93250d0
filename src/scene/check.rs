//! Mesh checks: closedness and orientation (edge use counts), area per surface, and the
//! enclosed air volume by the divergence theorem per connected component.

use std::collections::HashMap;

use glam::{DVec3, Vec3};

use crate::core::TriangleMesh;

/// Topology and measures of a mesh. Vertices are welded by exact position first, so meshes
/// that repeat vertices per object or per group are judged by their geometry.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MeshReport {
    /// Number of triangles.
    pub triangles: usize,
    /// Number of distinct vertices (welded by exact position).
    pub distinct_vertices: usize,
    /// Number of distinct edges.
    pub edges: usize,
    /// Edges used by exactly one triangle (holes, open sheets).
    pub open_edges: usize,
    /// Edges used by more than two triangles (internal sheets, T-shaped joins).
    pub over_shared_edges: usize,
    /// Two-triangle edges whose triangles run the edge in the same direction (flipped faces).
    pub misoriented_edges: usize,
    /// Total area, m^2.
    pub total_area_m2: f64,
    /// Area per surface id, square metres.
    pub area_by_surface_m2: Vec<f64>,
    /// Components of triangles connected through two-triangle edges, largest volume first.
    pub components: Vec<ComponentReport>,
    /// Index into `components` of each triangle.
    pub component_of_triangle: Vec<u32>,
    /// Sum of signed tetrahedron volumes over all triangles (divergence theorem), m^3.
    pub divergence_volume_m3: f64,
    /// Volume of air: the largest closed component (the room shell) minus the closed
    /// components inside it (obstacles), m^3; `None` when no closed component encloses all
    /// the others (an open or outdoor scene).
    pub air_volume_m3: Option<f64>,
    /// With an air volume: whether the shell's normals point out of the air (positive signed
    /// volume), as in BRAS and propsim's rooms; the inside test needs to know.
    pub normals_point_out_of_air: Option<bool>,
    /// Placed copies of meshes ([`add_instances`]); `triangles` and the edge counts include
    /// every copy's.
    pub instances: usize,
    /// Triangles stored once: the mesh's and one copy of each instanced mesh.
    pub unique_triangles: usize,
    /// Components of all the copies together (not in `components`).
    pub instanced_components: usize,
    /// Closed components of all the copies together.
    pub instanced_closed_components: usize,
}

/// One connected component.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ComponentReport {
    /// Number of triangles.
    pub triangles: usize,
    /// Area, m^2.
    pub area_m2: f64,
    /// Signed volume; positive when normals point outward of the enclosed region.
    pub signed_volume_m3: f64,
    /// No edge of the component is used by only one triangle.
    pub closed: bool,
    /// All triangles lie in one plane (a zero-thickness sheet, e.g. a partition between two
    /// solids that share it).
    pub planar: bool,
    /// Bounding box corners (lower, upper), metres.
    pub bounds: (Vec3, Vec3),
}

impl MeshReport {
    /// Whether every edge is shared by exactly two triangles.
    pub fn is_closed(&self) -> bool {
        self.triangles > 0 && self.open_edges == 0 && self.over_shared_edges == 0
    }

    /// Whether no edge has flipped neighbours.
    pub fn is_consistently_oriented(&self) -> bool {
        self.misoriented_edges == 0
    }
}

fn find(parent: &mut [u32], mut i: u32) -> u32 {
    while parent[i as usize] != i {
        parent[i as usize] = parent[parent[i as usize] as usize];
        i = parent[i as usize];
    }
    i
}

/// Computes the [`MeshReport`] of `mesh`.
pub fn analyze(mesh: &TriangleMesh) -> MeshReport {
    // Weld by exact coordinates (+0.0 and -0.0 alike).
    let key = |p: Vec3| (p + Vec3::ZERO).to_array().map(f32::to_bits);
    let mut weld: HashMap<[u32; 3], u32> = HashMap::new();
    let vid: Vec<u32> = mesh
        .positions
        .iter()
        .map(|&p| {
            let n = weld.len() as u32;
            *weld.entry(key(p)).or_insert(n)
        })
        .collect();

    let n = mesh.triangle_count();
    // Undirected edge -> (use count, sum of directions: +1 for a->b with a<b, -1 otherwise,
    // first triangle).
    let mut edges: HashMap<(u32, u32), (u32, i32, u32)> = HashMap::with_capacity(n * 3 / 2 + 1);
    for (t, tri) in mesh.triangles.iter().enumerate() {
        let v = tri.map(|i| vid[i as usize]);
        for k in 0..3 {
            let (a, b) = (v[k], v[(k + 1) % 3]);
            let (lo, hi, dir) = if a < b { (a, b, 1) } else { (b, a, -1) };
            let e = edges.entry((lo, hi)).or_insert((0, 0, t as u32));
            e.0 += 1;
            e.1 += dir;
        }
    }

    let mut parent: Vec<u32> = (0..n as u32).collect();
    let mut report = MeshReport {
        triangles: n,
        distinct_vertices: weld.len(),
        edges: edges.len(),
        area_by_surface_m2: vec![0.0; mesh.surface_names.len()],
        ..Default::default()
    };
    // Second pass to union the two triangles of each manifold edge.
    let mut first_of: HashMap<(u32, u32), u32> = HashMap::with_capacity(edges.len());
    for (t, tri) in mesh.triangles.iter().enumerate() {
        let v = tri.map(|i| vid[i as usize]);
        for k in 0..3 {
            let (a, b) = (v[k], v[(k + 1) % 3]);
            let e = (a.min(b), a.max(b));
            if edges[&e].0 == 2 {
                match first_of.get(&e) {
                    Some(&other) => {
                        let (ra, rb) = (find(&mut parent, other), find(&mut parent, t as u32));
                        parent[ra as usize] = rb;
                    }
                    None => {
                        first_of.insert(e, t as u32);
                    }
                }
            }
        }
    }
    for &(count, dir_sum, _) in edges.values() {
        match count {
            1 => report.open_edges += 1,
            2 if dir_sum != 0 => report.misoriented_edges += 1,
            2 => {}
            _ => report.over_shared_edges += 1,
        }
    }
    // A component with an edge used once (a hole, a loose panel) is open. Edges shared by
    // more than two triangles (an internal sheet between two solids) do not open it.
    let mut root_of: Vec<u32> = (0..n as u32).map(|t| find(&mut parent, t)).collect();
    let mut component_open: HashMap<u32, bool> = HashMap::new();
    for &(count, _, first) in edges.values() {
        if count == 1 {
            component_open.insert(root_of[first as usize], true);
        }
    }

    let mut comps: HashMap<u32, ComponentReport> = HashMap::new();
    // Normal and a point of each component's first triangle, for the planarity test.
    let mut plane_of: HashMap<u32, (DVec3, DVec3)> = HashMap::new();
    for (t, &root) in root_of.iter().enumerate() {
        let [a, b, c_] = mesh.corners(t).map(|p| p.as_dvec3());
        let area = 0.5 * (b - a).cross(c_ - a).length();
        let vol = a.dot(b.cross(c_)) / 6.0;
        report.total_area_m2 += area;
        report.divergence_volume_m3 += vol;
        if let Some(s) = report.area_by_surface_m2.get_mut(mesh.surface_of_triangle[t] as usize) {
            *s += area;
        }
        let lo_hi = mesh.corners(t);
        let c = comps.entry(root).or_insert_with(|| ComponentReport {
            closed: !component_open.get(&root).copied().unwrap_or(false),
            bounds: (lo_hi[0], lo_hi[0]),
            ..Default::default()
        });
        let normal = (b - a).cross(c_ - a).normalize_or_zero();
        let (n0, p0) = *plane_of.entry(root).or_insert((normal, a));
        if c.triangles == 0 {
            c.planar = true;
        }
        let off_plane = |p: DVec3| (p - p0).dot(n0).abs() > 1e-6 * (1.0 + p.abs().max_element());
        if c.planar && (normal.cross(n0).length() > 1e-6 || [a, b, c_].into_iter().any(off_plane)) {
            c.planar = false;
        }
        c.triangles += 1;
        c.area_m2 += area;
        c.signed_volume_m3 += vol;
        for p in lo_hi {
            c.bounds = (c.bounds.0.min(p), c.bounds.1.max(p));
        }
    }
    let mut keyed: Vec<(u32, ComponentReport)> = comps.into_iter().collect();
    keyed.sort_by(|(ra, a), (rb, b)| {
        b.signed_volume_m3
            .abs()
            .total_cmp(&a.signed_volume_m3.abs())
            .then(b.triangles.cmp(&a.triangles))
            .then(ra.cmp(rb))
    });
    let index_of_root: HashMap<u32, u32> =
        keyed.iter().enumerate().map(|(i, (r, _))| (*r, i as u32)).collect();
    for r in &mut root_of {
        *r = index_of_root[r];
    }
    report.component_of_triangle = root_of;
    let components: Vec<ComponentReport> = keyed.into_iter().map(|(_, c)| c).collect();
    // Air is bounded when the largest closed component (the room shell) encloses every other
    // component (obstacles, hanging panels); closed components inside it are subtracted.
    let shell = components.iter().position(|c| c.closed);
    if let Some(shell) = shell.map(|i| &components[i]) {
        let inside = |c: &ComponentReport| {
            let pad = 1e-4 * (1.0 + shell.bounds.1.abs().max(shell.bounds.0.abs()).max_element());
            c.bounds.0.cmpge(shell.bounds.0 - pad).all() && c.bounds.1.cmple(shell.bounds.1 + pad).all()
        };
        if components.iter().all(inside) {
            let obstacles: f64 = components
                .iter()
                .filter(|c| c.closed && !c.planar && !std::ptr::eq(*c, shell))
                .map(|c| c.signed_volume_m3.abs())
                .sum();
            report.air_volume_m3 = Some(shell.signed_volume_m3.abs() - obstacles);
            report.normals_point_out_of_air = Some(shell.signed_volume_m3 > 0.0);
        }
    }
    report.components = components;
    report
}

/// `Some(s^2)` when the linear map `m` is a similarity (`m^T m = s^2 I`, a rotation or mirror
/// times a uniform scale), whose areas all scale by `s^2`.
fn similarity_area_factor(m: glam::Mat3A) -> Option<f64> {
    let g = m.transpose() * m;
    let s2 = g.x_axis.x;
    let off = (g - glam::Mat3A::from_diagonal(glam::Vec3::splat(s2))).to_cols_array();
    off.iter().all(|v| v.abs() <= 1e-6 * s2).then_some(f64::from(s2))
}

/// `report` (of the scene's own mesh) with the copies of `instances` added: an affine map
/// keeps a mesh's topology, so edge and component counts add up, closed stays closed and
/// planar stays planar; areas are mapped exactly (scaled by `s^2` under a similarity, else
/// triangle by triangle) and volumes scale by `|det|` (mirrored copies are rewound). The
/// copies' closed, non-planar components inside the room shell are obstacles whose volume
/// leaves the air; a copy reaching outside the shell leaves the scene without air.
/// `mesh_reports[i]` is [`analyze`] of `meshes[i]`.
pub fn add_instances(
    mut report: MeshReport,
    meshes: &[TriangleMesh],
    mesh_reports: &[MeshReport],
    instances: &[crate::core::Instance],
) -> MeshReport {
    report.unique_triangles = report.triangles + mesh_reports.iter().map(|r| r.triangles).sum::<usize>();
    report.instances = instances.len();
    let mut obstacles_m3 = 0.0;
    let mut all_inside = true;
    let shell = report.components.iter().find(|c| c.closed).map(|c| c.bounds);
    for inst in instances {
        let (m, r) = (&meshes[inst.mesh as usize], &mesh_reports[inst.mesh as usize]);
        report.triangles += r.triangles;
        report.distinct_vertices += r.distinct_vertices;
        report.edges += r.edges;
        report.open_edges += r.open_edges;
        report.over_shared_edges += r.over_shared_edges;
        report.misoriented_edges += r.misoriented_edges;
        report.instanced_components += r.components.len();
        report.instanced_closed_components += r.components.iter().filter(|c| c.closed).count();
        let linear = inst.object_to_world.matrix3;
        let det = f64::from(linear.determinant()).abs();
        let surface = |local: usize| inst.surfaces.get(local).copied().unwrap_or(local as u32) as usize;
        match similarity_area_factor(linear) {
            Some(s2) => {
                report.total_area_m2 += r.total_area_m2 * s2;
                for (local, a) in r.area_by_surface_m2.iter().enumerate() {
                    if let Some(slot) = report.area_by_surface_m2.get_mut(surface(local)) {
                        *slot += a * s2;
                    }
                }
            }
            None => {
                for t in 0..m.triangle_count() {
                    let [a, b, c] = m.corners(t).map(|p| inst.object_to_world.transform_point3(p).as_dvec3());
                    let area = 0.5 * (b - a).cross(c - a).length();
                    report.total_area_m2 += area;
                    if let Some(slot) =
                        report.area_by_surface_m2.get_mut(surface(m.surface_of_triangle[t] as usize))
                    {
                        *slot += area;
                    }
                }
            }
        }
        report.divergence_volume_m3 += r.divergence_volume_m3 * det;
        obstacles_m3 += r
            .components
            .iter()
            .filter(|c| c.closed && !c.planar)
            .map(|c| c.signed_volume_m3.abs())
            .sum::<f64>()
            * det;
        if let (Some((lo, hi)), Some((slo, shi))) = (m.bounds(), shell) {
            let (wlo, whi) = crate::core::accel::instances::transformed_box(&inst.object_to_world, lo, hi);
            let pad = 1e-4 * (1.0 + shi.abs().max(slo.abs()).max_element());
            all_inside &= wlo.cmpge(slo - pad).all() && whi.cmple(shi + pad).all();
        }
    }
    if let Some(air) = report.air_volume_m3 {
        if all_inside {
            report.air_volume_m3 = Some(air - obstacles_m3);
        } else {
            report.air_volume_m3 = None;
            report.normals_point_out_of_air = None;
        }
    }
    report
}

/// Signed volume of a closed, outward-oriented triangle soup (divergence theorem), m^3.
pub fn signed_volume(mesh: &TriangleMesh) -> f64 {
    (0..mesh.triangle_count())
        .map(|t| {
            let [a, b, c]: [DVec3; 3] = mesh.corners(t).map(|p| p.as_dvec3());
            a.dot(b.cross(c)) / 6.0
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn room_with_obstacle() -> TriangleMesh {
        let mut m = TriangleMesh::default();
        let wall = m.surface_id("wall");
        let block = m.surface_id("block");
        m.push_box(Vec3::ZERO, Vec3::new(10.0, 8.0, 3.0), 2, wall);
        // An obstacle inside, wound like the walls (normals into the obstacle).
        let start = m.triangle_count();
        m.push_box(Vec3::new(1.0, 1.0, 0.0), Vec3::new(2.0, 3.0, 1.0), 1, block);
        for t in &mut m.triangles[start..] {
            t.swap(1, 2);
        }
        m
    }

    #[test]
    fn closed_box_volume_area_and_topology() {
        let mut m = TriangleMesh::default();
        let s = m.surface_id("wall");
        m.push_box(Vec3::ZERO, Vec3::new(10.0, 8.0, 3.0), 3, s);
        let r = analyze(&m);
        assert!(r.is_closed() && r.is_consistently_oriented());
        assert!((r.total_area_m2 - 268.0).abs() < 1e-6);
        assert!((r.air_volume_m3.unwrap() - 240.0).abs() < 1e-6);
        assert_eq!(r.components.len(), 1);
        assert!(r.components[0].signed_volume_m3 > 0.0);
        assert!((signed_volume(&m) - 240.0).abs() < 1e-6);
    }

    #[test]
    fn obstacles_are_subtracted_from_air() {
        let r = analyze(&room_with_obstacle());
        assert!(r.is_closed());
        assert_eq!(r.components.len(), 2);
        assert!((r.air_volume_m3.unwrap() - (240.0 - 2.0)).abs() < 1e-6);
        assert!((r.area_by_surface_m2[1] - 10.0).abs() < 1e-6);
    }

    #[test]
    fn detects_holes_flips_and_over_shared_edges() {
        let mut m = TriangleMesh::default();
        let s = m.surface_id("wall");
        m.push_box(Vec3::ZERO, Vec3::ONE, 1, s);
        let mut holed = m.clone();
        holed.triangles.pop();
        holed.surface_of_triangle.pop();
        let r = analyze(&holed);
        assert_eq!(r.open_edges, 3);
        assert!(!r.is_closed());
        assert_eq!(r.air_volume_m3, None);

        let mut flipped = m.clone();
        flipped.triangles[0].swap(1, 2);
        assert_eq!(analyze(&flipped).misoriented_edges, 3);

        // An internal sheet on the diagonal plane x = y shares the box's vertical edges.
        let mut sheet = m.clone();
        sheet.push_quad(
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(1.0, 1.0, 1.0),
            Vec3::new(0.0, 0.0, 1.0),
            s,
        );
        let r = analyze(&sheet);
        assert!(r.over_shared_edges >= 2, "{r:?}");
        assert!(!r.is_closed());
    }
}
