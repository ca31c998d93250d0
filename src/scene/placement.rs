//! Where things go in a scene: points as users write them (`X,Y,Z`) and automatic placement
//! of a source or receiver inside a room when the user gives none.

use glam::Vec3;

use super::World;
use crate::core::Ray;
use crate::core::rng::{stream, uniform};

/// Parses "x,y,z" into three finite numbers.
pub fn parse_point(s: &str) -> Result<[f32; 3], String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    if parts.len() != 3 {
        return Err(format!("\"{s}\": expected X,Y,Z"));
    }
    let mut out = [0.0; 3];
    for (o, p) in out.iter_mut().zip(&parts) {
        let v: f32 = p.parse().map_err(|_| format!("\"{p}\" is not a number"))?;
        if !v.is_finite() {
            return Err(format!("\"{p}\" is not finite"));
        }
        *o = v;
    }
    Ok(out)
}

/// Parses "x,y" into two finite numbers.
pub fn parse_xy(s: &str) -> Result<[f64; 2], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|p| p.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("\"{s}\": expected X,Y"))?;
    match v[..] {
        [x, y] if x.is_finite() && y.is_finite() => Ok([x, y]),
        _ => Err(format!("\"{s}\": expected two finite numbers X,Y")),
    }
}

/// Picks a point inside the room at least `clearance_m` from every surface (along the six
/// axis directions), trying the relative position `hint` in the bounding box first, then a
/// deterministic random search; `None` when no such point turns up.
pub fn place_inside(world: &World, hint: Vec3, clearance_m: f32) -> Option<Vec3> {
    let (lo, hi) = world.scene.mesh.bounds()?;
    let clear = |p: Vec3| {
        world.is_inside(p) == Some(true)
            && [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z]
                .iter()
                .all(|d| world.accel.mesh.closest_hit(&Ray::new(p, *d)).is_none_or(|h| h.t >= clearance_m))
    };
    let first = lo + (hi - lo) * hint;
    if clear(first) {
        return Some(first);
    }
    (0..20_000u64).find_map(|i| {
        let mut r = stream(7, 0x91ace, i);
        let p = lo + (hi - lo) * Vec3::new(uniform(&mut r), uniform(&mut r), uniform(&mut r));
        clear(p).then_some(p)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_parse_and_reject_garbage() {
        assert_eq!(parse_point("1, 2.5,-3").unwrap(), [1.0, 2.5, -3.0]);
        assert!(parse_point("1,2").is_err());
        assert!(parse_point("1,2,nan").is_err());
        assert!(parse_point("a,b,c").is_err());
        assert_eq!(parse_xy("-1,2").unwrap(), [-1.0, 2.0]);
        assert!(parse_xy("1,inf").is_err());
    }
}
