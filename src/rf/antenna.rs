//! Transmit antennas: gain pattern and polarisation direction of the radiated field.

use glam::DVec3;

/// Polarisation of an isotropic antenna's field (a dipole's is set by its axis).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Polarization {
    /// Field in the vertical plane containing the direction (like a vertical dipole).
    Vertical,
    /// Field horizontal, perpendicular to the direction (like a horizontal loop).
    Horizontal,
}

impl std::str::FromStr for Polarization {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s.to_ascii_lowercase().as_str() {
            "vertical" | "v" => Ok(Self::Vertical),
            "horizontal" | "h" => Ok(Self::Horizontal),
            _ => Err(format!("polarization \"{s}\": expected vertical or horizontal")),
        }
    }
}

/// Directivity of a half-wave dipole at broadside, `1.6409` (2.15 dBi) (Balanis, Antenna
/// Theory, 4th ed., eq. 4-91).
pub const HALF_WAVE_DIPOLE_DIRECTIVITY: f64 = 1.640_922_376_984_585;

/// A transmit antenna.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Antenna {
    /// Gain 1 in every direction, with the given polarisation.
    Isotropic {
        /// The polarisation.
        polarization: Polarization,
    },
    /// A lossless half-wave dipole along `axis` (unit vector): gain
    /// `G(psi) = 1.6409 [cos(pi/2 cos psi) / sin psi]^2`, psi the angle from the axis
    /// (Balanis eq. 4-84, normalised to the directivity of eq. 4-91); the field is along
    /// the axis' projection perpendicular to the direction.
    Dipole {
        /// Unit vector along the dipole.
        axis: DVec3,
    },
}

impl Antenna {
    /// Power gain in the (unit) direction `dir`, linear.
    #[inline]
    pub fn gain(&self, dir: DVec3) -> f64 {
        match *self {
            Antenna::Isotropic { .. } => 1.0,
            Antenna::Dipole { axis } => {
                let c = dir.dot(axis).clamp(-1.0, 1.0);
                let s2 = 1.0 - c * c;
                if s2 < 1e-12 {
                    return 0.0;
                }
                let f = (std::f64::consts::FRAC_PI_2 * c).cos();
                HALF_WAVE_DIPOLE_DIRECTIVITY * f * f / s2
            }
        }
    }

    /// Unit polarisation vector of the field radiated in the (unit) direction `dir`,
    /// perpendicular to `dir`.
    #[inline]
    pub fn polarization(&self, dir: DVec3) -> DVec3 {
        let reference = match *self {
            Antenna::Isotropic { polarization: Polarization::Vertical } => DVec3::Z,
            Antenna::Isotropic { polarization: Polarization::Horizontal } => {
                let h = dir.cross(DVec3::Z);
                if h.length_squared() > 1e-12 {
                    return h.normalize();
                }
                DVec3::X
            }
            Antenna::Dipole { axis } => axis,
        };
        let e = reference - reference.dot(dir) * dir;
        if e.length_squared() > 1e-12 {
            return e.normalize();
        }
        // Along the reference axis the field direction is undefined (and a dipole radiates
        // nothing there): pick any perpendicular.
        let any = if dir.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
        (any - any.dot(dir) * dir).normalize()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dipole_gain_integrates_to_4_pi_and_has_nulls_on_axis() {
        let a = Antenna::Dipole { axis: DVec3::Z };
        let n = 20_000;
        let mut sum = 0.0;
        for i in 0..n {
            let c = -1.0 + (2.0 * f64::from(i) + 1.0) / f64::from(n);
            sum += a.gain(DVec3::new((1.0 - c * c).sqrt(), 0.0, c));
        }
        // (1/4pi) integral G dOmega = (1/2) integral G dcos = 1 for a lossless antenna.
        assert!((sum / f64::from(n) - 1.0).abs() < 1e-3, "{}", sum / f64::from(n));
        assert_eq!(a.gain(DVec3::Z), 0.0);
        assert!((a.gain(DVec3::X) - 1.6409).abs() < 1e-4);
    }

    #[test]
    fn polarisations_are_perpendicular_and_as_named() {
        let d = DVec3::new(0.6, 0.0, -0.8);
        let v = Antenna::Isotropic { polarization: Polarization::Vertical }.polarization(d);
        let h = Antenna::Isotropic { polarization: Polarization::Horizontal }.polarization(d);
        assert!(v.dot(d).abs() < 1e-12 && h.dot(d).abs() < 1e-12);
        assert!(h.z.abs() < 1e-12 && v.y.abs() < 1e-12);
        let x = Antenna::Dipole { axis: DVec3::X }.polarization(DVec3::Y);
        assert!((x - DVec3::X).length() < 1e-12);
        assert!("Vertical".parse::<Polarization>().is_ok() && "diag".parse::<Polarization>().is_err());
    }
}
