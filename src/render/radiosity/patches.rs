//! Patches: the scene's mesh triangles as the roots of the element hierarchy, each with the
//! diffuse reflectance and emission radiosity uses, and the midpoint subdivision that makes
//! smaller elements.
//!
//! Radiosity is the diffuse part of light transport, so every surface is taken as a Lambert
//! reflector: a metal as a Lambert surface of albedo `f0`, a glass as one of albedo `tint`
//! (the light it would pass); [`PatchMaterial::approximated`] says which surfaces were.

use glam::Vec3;

use super::form_factor::Tri;
use crate::render::bsdf::Bsdf;
use crate::render::{RenderScene, SurfaceOptics};

/// No element (a degenerate triangle's root).
pub const NONE: u32 = u32::MAX;

/// What radiosity takes of a surface's optics.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PatchMaterial {
    /// Diffuse reflectance in [0, 1] per channel.
    pub rho: Vec3,
    /// Radiance emitted from the front face.
    pub emission: Vec3,
    /// Whether the surface is not Lambertian and was approximated by a diffuse one.
    pub approximated: bool,
}

impl PatchMaterial {
    /// The diffuse stand-in of `optics` (see the module's doc).
    pub fn of(optics: &SurfaceOptics) -> Self {
        let (rho, approximated) = match optics.bsdf {
            Bsdf::Lambert { albedo } => (albedo, false),
            Bsdf::Metal { f0, .. } => (f0, true),
            Bsdf::Dielectric { tint, .. } => (tint, true),
        };
        let rho = if rho.is_finite() { rho.clamp(Vec3::ZERO, Vec3::ONE) } else { Vec3::ZERO };
        Self { rho, emission: optics.emission, approximated }
    }
}

/// A link: the form factors from the element that holds it (the receiver) to `source`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Link {
    /// The source element.
    pub source: u32,
    /// `f[a][b]`: form factor from side `a` of the receiver to side `b` of the source
    /// (0 front, 1 back).
    pub f: [[f32; 2]; 2],
}

/// One element of the hierarchy: a triangle, its radiance and its links.
#[derive(Clone, Debug)]
pub struct Element {
    /// The triangle.
    pub tri: Tri,
    /// Its surface's diffuse stand-in.
    pub material: PatchMaterial,
    /// Index of the first of the four children, [`NONE`] for a leaf.
    pub children: u32,
    /// Radiance leaving the front and the back side (for a parent, the area-weighted mean of
    /// its children's).
    pub radiance: [Vec3; 2],
    /// Links gathering light into this element.
    pub links: Vec<Link>,
}

/// Every element: the roots (one a mesh triangle) and their subdivisions.
#[derive(Clone, Debug, Default)]
pub struct Hierarchy {
    /// The elements; children of one parent are consecutive.
    pub elements: Vec<Element>,
    /// The root element of each mesh triangle ([`NONE`] for a degenerate one).
    pub roots: Vec<u32>,
    /// Most elements allowed.
    pub max_elements: usize,
    /// Surfaces approximated by a diffuse stand-in.
    pub approximated: usize,
}

impl Hierarchy {
    /// One root per non-degenerate mesh triangle of `scene`; more than `max_elements` is an error.
    pub fn roots(scene: &RenderScene, max_elements: usize) -> Result<Self, String> {
        let materials: Vec<PatchMaterial> = scene.surfaces.iter().map(PatchMaterial::of).collect();
        let mesh = scene.mesh();
        let count = mesh.triangle_count();
        if count > max_elements {
            return Err(budget_error(max_elements));
        }
        let mut h = Hierarchy { max_elements, ..Self::default() };
        for i in 0..count {
            let Some(tri) = Tri::new(mesh.corners(i)) else {
                h.roots.push(NONE);
                continue;
            };
            let material = materials[mesh.surface_of_triangle[i] as usize];
            h.roots.push(h.elements.len() as u32);
            h.elements.push(Element {
                tri,
                material,
                children: NONE,
                radiance: [material.emission, Vec3::ZERO],
                links: Vec::new(),
            });
        }
        h.approximated = materials.iter().filter(|m| m.approximated).count();
        Ok(h)
    }

    /// The root elements, in mesh order.
    pub fn root_elements(&self) -> Vec<u32> {
        self.roots.iter().copied().filter(|&r| r != NONE).collect()
    }

    /// Splits element `e` into four (once) and returns the first child's index; an error when
    /// that would exceed the budget.
    pub fn split(&mut self, e: u32) -> Result<u32, String> {
        let parent = &self.elements[e as usize];
        if parent.children != NONE {
            return Ok(parent.children);
        }
        if self.elements.len() + 4 > self.max_elements {
            return Err(budget_error(self.max_elements));
        }
        let (material, radiance) = (parent.material, parent.radiance);
        let first = self.elements.len() as u32;
        for tri in parent.tri.split() {
            self.elements.push(Element { tri, material, children: NONE, radiance, links: Vec::new() });
        }
        self.elements[e as usize].children = first;
        Ok(first)
    }

    /// The leaf of mesh triangle `triangle` that holds `point` (a point on the triangle).
    pub fn leaf_at(&self, triangle: u32, point: Vec3) -> Option<u32> {
        let mut e = *self.roots.get(triangle as usize)?;
        if e == NONE {
            return None;
        }
        loop {
            let c = self.elements[e as usize].children;
            if c == NONE {
                return Some(e);
            }
            let inside = |i: u32| self.elements[(c + i) as usize].tri.min_barycentric(point);
            e = c + (1..4).fold(0, |best, i| if inside(i) > inside(best) { i } else { best });
        }
    }

    /// Number of leaves.
    pub fn leaves(&self) -> usize {
        self.elements.iter().filter(|e| e.children == NONE).count()
    }

    /// Number of links.
    pub fn links(&self) -> usize {
        self.elements.iter().map(|e| e.links.len()).sum()
    }
}

/// The one-line error of a patch budget exceeded.
pub fn budget_error(max: usize) -> String {
    format!(
        "radiosity: more than {max} patches needed (--radiosity-max-patches); raise it, or coarsen \
         with --radiosity-patches, --radiosity-patch-area or --radiosity-refine"
    )
}
