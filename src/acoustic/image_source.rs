//! The image-source method for the early specular reflections: the acoustic payload of the
//! core's specular-path engine ([`crate::core::specular`]: Allen & Berkley 1979; Borish 1984
//! for arbitrary polyhedra), which finds and validates the paths, the same ones the radio
//! receivers use.

use glam::{DVec3, Vec3};

use super::directivity::Directivity;
use super::edge_scattering::EdgeScattering;
use super::tracer::SurfaceAcoustics;
use crate::core::Accel;
use crate::core::specular::{Planes, specular_paths};
use crate::scene::materials::{BAND_COUNT, BandValues};

/// One specular arrival at a receiver.
#[derive(Clone, Debug, PartialEq)]
pub struct Arrival {
    /// Path length, metres.
    pub length_m: f64,
    /// Reflections on the way.
    pub order: usize,
    /// Energy fluence per band per joule of source energy, 1/m^2:
    /// `prod (1 - a)(1 - s) e^{-m L} / (4 pi L^2)`, the point source's spherical spreading
    /// (Allen & Berkley 1979) with each reflection keeping its specular, unabsorbed part and
    /// the air's energy attenuation `m` (ISO 9613-1) over the whole length.
    pub energy: [f64; BAND_COUNT],
    /// Unit vector from the source towards the path's first reflection point (the receiver
    /// for the direct sound): the direction of emission, in which the source's directivity
    /// weights the path.
    pub emitted: [f64; 3],
    /// Unit vector from the receiver towards the path's last reflection point (the source for
    /// the direct sound): the direction the sound arrives from.
    pub incoming: [f64; 3],
    /// True for a path diffracted by an edge ([`super::diffraction`]), false for the direct
    /// sound and specular reflections.
    pub diffracted: bool,
}

/// The specular arrivals of up to `order` reflections from `source` to `receiver`, in the
/// engine's order (the direct sound first if it is free). `surfaces` gives each surface id's
/// absorption and scattering (a surface missing from it absorbs everything), `air_per_m` the
/// air's attenuation per band.
pub fn specular_arrivals(
    accel: &Accel,
    planes: &Planes,
    surfaces: &[SurfaceAcoustics],
    air_per_m: &BandValues,
    source: Vec3,
    receiver: Vec3,
    order: u32,
) -> Vec<Arrival> {
    specular_arrivals_from(
        accel,
        planes,
        surfaces,
        None,
        air_per_m,
        (source, &Directivity::OMNI),
        receiver,
        order,
    )
}

/// [`specular_arrivals`] from a directional source: each path's energy is also weighted by
/// the source's normalised energy weight in its direction of emission ([`Arrival::emitted`];
/// docs/acoustics.md, Directivity), and with the finite panels' edge scattering
/// (`edge_scattering`, [`super::edge_scattering`]) taken from each reflection's specular part.
#[allow(clippy::too_many_arguments)]
pub fn specular_arrivals_from(
    accel: &Accel,
    planes: &Planes,
    surfaces: &[SurfaceAcoustics],
    edge_scattering: Option<&EdgeScattering>,
    air_per_m: &BandValues,
    (source, directivity): (Vec3, &Directivity),
    receiver: Vec3,
    order: u32,
) -> Vec<Arrival> {
    specular_paths(accel, planes, source.as_dvec3(), receiver.as_dvec3(), order)
        .into_iter()
        .map(|p| {
            let spreading = 1.0 / (4.0 * std::f64::consts::PI * p.length_m.powi(2));
            let points = p.points();
            let unit = |from: DVec3, to: DVec3| (to - from).try_normalize().unwrap_or(DVec3::X);
            let emitted = unit(points[0], points[1]);
            let incoming = unit(points[points.len() - 1], points[points.len() - 2]);
            let weight = directivity.energy_weights(emitted.as_vec3());
            let energy = std::array::from_fn(|b| {
                let mut e = spreading * f64::from(weight[b]) * (-f64::from(air_per_m[b]) * p.length_m).exp();
                for (i, r) in p.reflections.iter().enumerate() {
                    let Some(sa) = surfaces.get(r.surface as usize) else { return 0.0 };
                    let s = match edge_scattering {
                        Some(es) => {
                            let (d1, d2) =
                                (points[i].distance(points[i + 1]), points[i + 1].distance(points[i + 2]));
                            let all = es.scattering(
                                r.triangle,
                                &sa.scattering,
                                r.cos_incidence as f32,
                                d1 as f32,
                                Some(d2 as f32),
                            );
                            all[b]
                        }
                        None => sa.scattering[b],
                    };
                    e *= f64::from((1.0 - sa.absorption[b]) * (1.0 - s));
                }
                e
            });
            Arrival {
                length_m: p.length_m,
                order: p.order(),
                energy,
                emitted: emitted.to_array(),
                incoming: incoming.to_array(),
                diffracted: false,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::{BuildQuality, TriangleMesh};

    #[test]
    fn shoebox_arrivals_carry_the_closed_form_energy() {
        // Floor (absorption 0.3, scattering 0.1) and walls (0.1, 0.5) of a 10 x 8 x 3 m box,
        // air 2^-7 /m in every band: the direct sound and the floor image (2, 3, -1.5) carry
        // e^{-mL} / (4 pi L^2) and 0.7 x 0.9 e^{-mL} / (4 pi L^2).
        let mut mesh = TriangleMesh::default();
        let wall = mesh.surface_id("wall");
        mesh.push_box(Vec3::ZERO, Vec3::new(10.0, 8.0, 3.0), 1, wall);
        let floor = mesh.surface_id("floor");
        let floor_triangles: Vec<usize> =
            (0..mesh.triangle_count()).filter(|&t| mesh.corners(t).iter().all(|c| c.z == 0.0)).collect();
        assert_eq!(floor_triangles.len(), 2);
        for t in floor_triangles {
            mesh.surface_of_triangle[t] = floor;
        }
        let surfaces = [
            SurfaceAcoustics { absorption: [0.1; BAND_COUNT], scattering: [0.5; BAND_COUNT] },
            SurfaceAcoustics { absorption: [0.3; BAND_COUNT], scattering: [0.1; BAND_COUNT] },
        ];
        let accel = Accel::build(&mesh, Vec::new(), BuildQuality::default());
        let planes = Planes::of(&mesh);
        let (src, rcv) = (Vec3::new(2.0, 3.0, 1.5), Vec3::new(7.0, 5.0, 1.2));
        let arrivals = specular_arrivals(&accel, &planes, &surfaces, &[0.0078125; BAND_COUNT], src, rcv, 1);
        assert_eq!(arrivals.len(), 7);
        let expect = |length: f64, kept: f64| {
            kept * (-0.0078125 * length).exp() / (4.0 * std::f64::consts::PI * length * length)
        };
        let direct = rcv.as_dvec3().distance(src.as_dvec3());
        assert_eq!(arrivals[0].order, 0);
        assert!((arrivals[0].length_m - direct).abs() < 1e-9);
        for e in arrivals[0].energy {
            assert!((e / expect(direct, 1.0) - 1.0).abs() < 1e-12);
        }
        let floor_length = rcv.as_dvec3().distance(DVec3::new(2.0, 3.0, -1.5));
        let image = arrivals.iter().find(|a| (a.length_m - floor_length).abs() < 1e-9).unwrap();
        assert_eq!(image.order, 1);
        for e in image.energy {
            assert!((e / expect(floor_length, 0.7 * 0.9) - 1.0).abs() < 1e-6);
        }
        // The x = 10 wall: image (18, 3, 1.5).
        let wall_length = rcv.as_dvec3().distance(DVec3::new(18.0, 3.0, 1.5));
        let image = arrivals.iter().find(|a| (a.length_m - wall_length).abs() < 1e-9).unwrap();
        for e in image.energy {
            assert!((e / expect(wall_length, 0.9 * 0.5) - 1.0).abs() < 1e-6);
        }
    }
}
