//! ITU-R P.2040-3 Table 3: material constants of common building materials.
//! eps_r' = a f^b and sigma = c f^d S/m, f in GHz, within each entry's frequency range.

/// One row of ITU-R P.2040-3 Table 3.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ItuMaterial {
    /// snake_case name used in material files (`itu = "..."`).
    pub name: &'static str,
    /// Lower end of the valid frequency range, GHz (inclusive).
    pub freq_min_ghz: f64,
    /// Upper end of the valid frequency range, GHz (inclusive).
    pub freq_max_ghz: f64,
    /// `a` of `eps_r' = a f^b`.
    pub a: f64,
    /// `b` of `eps_r' = a f^b`.
    pub b: f64,
    /// `c` of `sigma = c f^d`.
    pub c: f64,
    /// `d` of `sigma = c f^d`.
    pub d: f64,
}

impl ItuMaterial {
    /// Real relative permittivity at `freq_ghz` (ITU-R P.2040-3 eq. 58).
    pub fn relative_permittivity(&self, freq_ghz: f64) -> f64 {
        self.a * freq_ghz.powf(self.b)
    }

    /// Conductivity in S/m at `freq_ghz` (ITU-R P.2040-3 eq. 59).
    pub fn conductivity_s_per_m(&self, freq_ghz: f64) -> f64 {
        self.c * freq_ghz.powf(self.d)
    }

    /// Whether `freq_ghz` lies in the valid frequency range.
    pub fn covers(&self, freq_ghz: f64) -> bool {
        (self.freq_min_ghz..=self.freq_max_ghz).contains(&freq_ghz)
    }
}

const fn row(name: &'static str, f: (f64, f64), a: f64, b: f64, c: f64, d: f64) -> ItuMaterial {
    ItuMaterial { name, freq_min_ghz: f.0, freq_max_ghz: f.1, a, b, c, d }
}

/// Every row of ITU-R P.2040-3 Table 3 (glass and ceiling board have two frequency ranges).
pub const ITU_P2040_TABLE3: [ItuMaterial; 16] = [
    row("concrete", (1.0, 100.0), 5.24, 0.0, 0.0462, 0.7822),
    row("brick", (1.0, 40.0), 3.91, 0.0, 0.0238, 0.16),
    row("plasterboard", (1.0, 100.0), 2.73, 0.0, 0.0085, 0.9395),
    row("wood", (0.001, 100.0), 1.99, 0.0, 0.0047, 1.0718),
    row("glass", (0.1, 100.0), 6.31, 0.0, 0.0036, 1.3394),
    row("glass", (220.0, 450.0), 5.79, 0.0, 0.0004, 1.658),
    row("ceiling_board", (1.0, 100.0), 1.48, 0.0, 0.0011, 1.0750),
    row("ceiling_board", (220.0, 450.0), 1.52, 0.0, 0.0029, 1.029),
    row("chipboard", (1.0, 100.0), 2.58, 0.0, 0.0217, 0.78),
    row("plywood", (1.0, 40.0), 2.71, 0.0, 0.33, 0.0),
    row("marble", (1.0, 60.0), 7.074, 0.0, 0.0055, 0.9262),
    row("floorboard", (50.0, 100.0), 3.66, 0.0, 0.0044, 1.3515),
    row("metal", (1.0, 100.0), 1.0, 0.0, 1.0e7, 0.0),
    row("very_dry_ground", (1.0, 10.0), 3.0, 0.0, 0.00015, 2.52),
    row("medium_dry_ground", (1.0, 10.0), 15.0, -0.1, 0.035, 1.63),
    row("wet_ground", (1.0, 10.0), 30.0, -0.4, 0.15, 1.30),
];

/// Distinct material names of Table 3, in table order.
pub fn itu_names() -> Vec<&'static str> {
    let mut names: Vec<&'static str> = Vec::new();
    for m in &ITU_P2040_TABLE3 {
        if !names.contains(&m.name) {
            names.push(m.name);
        }
    }
    names
}

/// The row for `name` that covers `freq_ghz`, or, when none covers it, the nearest row in
/// frequency with `false` (the caller decides whether extrapolation is allowed).
pub fn itu_lookup(name: &str, freq_ghz: f64) -> Option<(ItuMaterial, bool)> {
    let rows = ITU_P2040_TABLE3.iter().filter(|m| m.name == name);
    let mut best: Option<(ItuMaterial, f64)> = None;
    for m in rows {
        if m.covers(freq_ghz) {
            return Some((*m, true));
        }
        let gap = (m.freq_min_ghz - freq_ghz).max(freq_ghz - m.freq_max_ghz);
        if best.is_none_or(|(_, g)| gap < g) {
            best = Some((*m, gap));
        }
    }
    best.map(|(m, _)| (m, false))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn conductivities_match_design_test_values() {
        // docs/radio.md, Reference values: 3.5 GHz concrete 0.1231, brick 0.02908, glass 0.01928;
        // 2.4 GHz concrete 0.09163 S/m.
        let at = |n: &str, f: f64| itu_lookup(n, f).unwrap().0.conductivity_s_per_m(f);
        assert!((at("concrete", 3.5) - 0.1231).abs() < 5e-4);
        assert!((at("brick", 3.5) - 0.02908).abs() < 5e-5);
        assert!((at("glass", 3.5) - 0.01928).abs() < 5e-5);
        assert!((at("concrete", 2.4) - 0.09163).abs() < 5e-5);
        assert_eq!(itu_lookup("concrete", 3.5).unwrap().0.relative_permittivity(3.5), 5.24);
    }

    #[test]
    fn ranges_are_enforced() {
        assert!(itu_lookup("floorboard", 3.5).is_some_and(|(_, ok)| !ok));
        assert!(itu_lookup("glass", 300.0).is_some_and(|(m, ok)| ok && m.a == 5.79));
        assert!(itu_lookup("unobtainium", 3.5).is_none());
        assert_eq!(itu_names().len(), 14);
    }
}
