//! `coverage.png` (and `coverage_TX.png` per transmitter): the path-gain map as a heat map
//! with a dB colour bar, the buildings' footprints (the walls cut at the grid height) and the
//! transmitters; `best_server.png` in the transmitters' colours; drawn with plotters
//! into an RGB buffer and written with `png`. Text uses DejaVu Sans shipped in
//! `assets/fonts` (its licence is next to it).

use std::path::Path;

use plotters::prelude::*;
use plotters::style::text_anchor;
use rayon::prelude::*;

use super::config::ColourRange;
use super::coverage::{Coverage, GridSpec};
use crate::core::TriangleMesh;
use crate::io::plot::{PALETTE, register_font, write_rgb_png};

/// Viridis (van der Walt & Smith, matplotlib), sampled at nine stops.
const VIRIDIS: [[u8; 3]; 9] = [
    [68, 1, 84],
    [71, 44, 122],
    [59, 81, 139],
    [44, 113, 142],
    [33, 144, 141],
    [39, 173, 129],
    [92, 200, 99],
    [170, 220, 50],
    [253, 231, 37],
];

/// The colour of `t` in [0, 1].
pub fn colormap(t: f64) -> RGBColor {
    let x = t.clamp(0.0, 1.0) * (VIRIDIS.len() - 1) as f64;
    let i = (x.floor() as usize).min(VIRIDIS.len() - 2);
    let f = x - i as f64;
    let mix = |a: u8, b: u8| (f64::from(a) + f * (f64::from(b) - f64::from(a))).round() as u8;
    let (a, b) = (VIRIDIS[i], VIRIDIS[i + 1]);
    RGBColor(mix(a[0], b[0]), mix(a[1], b[1]), mix(a[2], b[2]))
}

/// Segments where the mesh's triangles cross the plane `z = h`: the footprints of walls and
/// buildings at the grid height.
pub fn footprints(mesh: &TriangleMesh, h: f64) -> Vec<[(f64, f64); 2]> {
    let mut out = Vec::new();
    for i in 0..mesh.triangle_count() {
        let c = mesh.corners(i).map(|v| v.as_dvec3());
        let mut pts = Vec::with_capacity(2);
        for k in 0..3 {
            let (a, b) = (c[k], c[(k + 1) % 3]);
            let (da, db) = (a.z - h, b.z - h);
            if (da < 0.0) != (db < 0.0) {
                let t = da / (da - db);
                let p = a + (b - a) * t;
                pts.push((p.x, p.y));
            }
        }
        if pts.len() == 2 {
            out.push([pts[0], pts[1]]);
        }
    }
    out
}

/// What to draw besides the map.
pub struct PlotExtras<'a> {
    /// Title.
    pub title: &'a str,
    /// A second, smaller title line (the propagation settings).
    pub subtitle: &'a str,
    /// Wall footprints at the grid height: segments of (x, y) end points.
    pub footprints: &'a [[(f64, f64); 2]],
    /// Transmitter (x, y) positions and names.
    pub transmitters: &'a [(f64, f64)],
    /// Transmitter names.
    pub transmitter_names: &'a [String],
}

/// The highest and lowest reached value of the map, dB (`None` when no cell is reached).
pub fn map_extent_db(cov: &Coverage) -> Option<(f64, f64)> {
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    for &g in cov.path_gain.iter().filter(|&&g| g > 0.0) {
        let d = 10.0 * g.log10();
        lo = lo.min(d);
        hi = hi.max(d);
    }
    hi.is_finite().then_some((lo, hi))
}

/// The colour scale's range, dB, for `cov`: [`ColourRange::resolve`] over its extent (by
/// default from the maximum down 80 dB, or to the minimum if closer).
pub fn db_range(cov: &Coverage, range: &ColourRange) -> Option<(f64, f64)> {
    range.resolve(map_extent_db(cov))
}

/// What the strip right of the map explains.
enum Legend<'a> {
    /// A colour bar from `lo` to `hi` dB.
    Bar { lo: f64, hi: f64, label: &'a str },
    /// One swatch per category.
    Categories(&'a [(String, RGBColor)]),
}

/// Grey of the cells no ray reached.
const EMPTY: RGBColor = RGBColor(200, 200, 200);

/// Draws the map of `colour` per cell (`None`: grey) with `legend` into an RGB image of
/// about `width` pixels and writes it as PNG.
fn write_map_png(
    path: &Path,
    spec: GridSpec,
    colour: &(dyn Fn(usize) -> Option<RGBColor> + Sync),
    legend: Option<Legend>,
    extras: &PlotExtras,
    width: u32,
) -> anyhow::Result<()> {
    register_font();
    let (x0, y0) = (spec.min_m[0], spec.min_m[1]);
    let (x1, y1) = (x0 + spec.nx as f64 * spec.cell_m, y0 + spec.ny as f64 * spec.cell_m);
    let (left, right, top, bottom) = (70u32, 130u32, 56u32, 50u32);
    let map_w = width.saturating_sub(left + right).max(100);
    let map_h = ((f64::from(map_w) * (y1 - y0) / (x1 - x0)).round() as u32).clamp(100, 1600);
    let (w, h) = (left + map_w + right, top + map_h + bottom);
    let mut buf = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE)?;
        let centred = |size: i32| {
            ("sans-serif", size)
                .into_font()
                .color(&BLACK)
                .pos(text_anchor::Pos::new(text_anchor::HPos::Center, text_anchor::VPos::Top))
        };
        root.draw(&Text::new(extras.title, ((w / 2) as i32, 6), centred(18)))?;
        root.draw(&Text::new(extras.subtitle, ((w / 2) as i32, 30), centred(13)))?;
        let (main, bar) = root.split_horizontally(w - right + 10);
        let mut chart = ChartBuilder::on(&main)
            .margin_top(top)
            .margin_right(10)
            .x_label_area_size(bottom - 8)
            .y_label_area_size(left - 8)
            .build_cartesian_2d(x0..x1, y0..y1)?;
        chart
            .configure_mesh()
            .disable_mesh()
            .x_desc("x (m)")
            .y_desc("y (m)")
            .label_style(("sans-serif", 13))
            .draw()?;
        // The map, pixel by pixel, from each cell's colour worked out once.
        let cell_colour: Vec<RGBColor> =
            (0..spec.cells()).into_par_iter().map(|c| colour(c).unwrap_or(EMPTY)).collect();
        let area = chart.plotting_area().strip_coord_spec();
        let (pw, ph) = area.dim_in_pixel();
        for py in 0..ph {
            for px in 0..pw {
                let x = x0 + (f64::from(px) + 0.5) / f64::from(pw) * (x1 - x0);
                let y = y1 - (f64::from(py) + 0.5) / f64::from(ph) * (y1 - y0);
                let c = spec.cell_of(x, y).map_or(EMPTY, |c| cell_colour[c]);
                area.draw_pixel((px as i32, py as i32), &c)?;
            }
        }
        for seg in extras.footprints {
            chart.draw_series(std::iter::once(PathElement::new(
                vec![seg[0], seg[1]],
                WHITE.stroke_width(2),
            )))?;
        }
        for (i, &(x, y)) in extras.transmitters.iter().enumerate() {
            chart.draw_series(std::iter::once(Cross::new((x, y), 6, RED.stroke_width(2))))?;
            if extras.transmitters.len() > 1
                && let Some(name) = extras.transmitter_names.get(i)
            {
                let label = EmptyElement::at((x, y)) + Text::new(name.clone(), (8, -16), ("sans-serif", 13));
                chart.draw_series(std::iter::once(label))?;
            }
        }
        let (by0, by1) = (top as i32 + 8, (top + map_h) as i32 - 8);
        match legend {
            Some(Legend::Bar { lo, hi, label }) => {
                let bar_x = 10i32;
                let bar_w = 22i32;
                for py in by0..=by1 {
                    let t = 1.0 - f64::from(py - by0) / f64::from(by1 - by0);
                    bar.draw(&Rectangle::new([(bar_x, py), (bar_x + bar_w, py + 1)], colormap(t).filled()))?;
                }
                bar.draw(&Rectangle::new([(bar_x, by0), (bar_x + bar_w, by1 + 1)], BLACK.stroke_width(1)))?;
                let step = if hi - lo > 50.0 { 10.0 } else { 5.0 };
                let mut v = (lo / step).ceil() * step;
                while v <= hi + 1e-9 {
                    let py = by1 - ((v - lo) / (hi - lo) * f64::from(by1 - by0)).round() as i32;
                    bar.draw(&PathElement::new(vec![(bar_x + bar_w, py), (bar_x + bar_w + 4, py)], BLACK))?;
                    bar.draw(&Text::new(format!("{v:.0}"), (bar_x + bar_w + 7, py - 7), ("sans-serif", 13)))?;
                    v += step;
                }
                bar.draw(&Text::new(label, (bar_x - 4, by0 - 20), ("sans-serif", 13)))?;
            }
            Some(Legend::Categories(items)) => {
                bar.draw(&Text::new("best server", (6, by0 - 20), ("sans-serif", 13)))?;
                for (k, (name, c)) in items.iter().enumerate() {
                    let y = by0 + 20 * k as i32;
                    bar.draw(&Rectangle::new([(8, y), (24, y + 14)], c.filled()))?;
                    bar.draw(&Rectangle::new([(8, y), (24, y + 14)], BLACK.stroke_width(1)))?;
                    let short: String = name.chars().take(14).collect();
                    bar.draw(&Text::new(short, (30, y), ("sans-serif", 13)))?;
                }
            }
            None => {}
        }
        root.present()?;
    }
    write_rgb_png(path, w, h, &buf)
}

/// Draws the path-gain map `cov` with a colour bar over `range` (dB; `None`: an empty map,
/// all grey) into an RGB image of about `width` pixels and writes it as PNG.
pub fn write_coverage_png(
    path: &Path,
    cov: &Coverage,
    range: Option<(f64, f64)>,
    extras: &PlotExtras,
    width: u32,
) -> anyhow::Result<()> {
    let colour = |c: usize| match range {
        Some((lo, hi)) if cov.path_gain[c] > 0.0 => {
            Some(colormap((10.0 * cov.path_gain[c].log10() - lo) / (hi - lo)))
        }
        _ => None,
    };
    let legend = range.map(|(lo, hi)| Legend::Bar { lo, hi, label: "path gain (dB)" });
    write_map_png(path, cov.spec, &colour, legend, extras, width)
}

/// The colour of transmitter `i` on categorical charts.
pub fn transmitter_colour(i: usize) -> RGBColor {
    PALETTE[i % PALETTE.len()]
}

/// Draws the best server of every cell (`best[cell]`, an index into `names`; `None`: grey)
/// in the transmitters' colours, with a legend, and writes it as PNG.
pub fn write_best_server_png(
    path: &Path,
    spec: GridSpec,
    best: &[Option<usize>],
    names: &[String],
    extras: &PlotExtras,
    width: u32,
) -> anyhow::Result<()> {
    let items: Vec<(String, RGBColor)> =
        names.iter().enumerate().map(|(i, n)| (n.clone(), transmitter_colour(i))).collect();
    let colour = |c: usize| best.get(c).copied().flatten().map(transmitter_colour);
    write_map_png(path, spec, &colour, Some(Legend::Categories(&items)), extras, width)
}

/// The power-delay profile of one receiver as PNG: a stem per path at its delay (ns) up to
/// its gain `10 log10 |a|^2` (dB) from the chart's floor, with a circle at the top; one
/// colour per transmitter, `(name, [(delay_ns, gain_db)])` each, named in a legend when
/// there are several. The floor is 60 dB below the strongest path (or 5 dB below the
/// weakest, if that is higher).
pub fn write_pdp_png(
    path: &Path,
    receiver: &str,
    transmitters: &[(String, Vec<(f64, f64)>)],
) -> anyhow::Result<()> {
    register_font();
    let all = || transmitters.iter().flat_map(|(_, p)| p.iter().copied());
    let top = all().map(|p| p.1).fold(f64::NEG_INFINITY, f64::max);
    let bottom = all().map(|p| p.1).fold(f64::INFINITY, f64::min);
    let latest = all().map(|p| p.0).fold(f64::NEG_INFINITY, f64::max);
    let earliest = all().map(|p| p.0).fold(f64::INFINITY, f64::min);
    let (y0, y1) = if top.is_finite() {
        let y1 = (top / 5.0).ceil() * 5.0 + 5.0;
        (((bottom - 5.0).max(y1 - 65.0) / 5.0).floor() * 5.0, y1)
    } else {
        (-100.0, 0.0)
    };
    // The delays of the paths with a margin of 5 % of their spread (at least 1 ns) each side.
    let (x0, x1) = if latest.is_finite() {
        let margin = (0.05 * (latest - earliest)).max(1.0);
        ((earliest - margin).max(0.0), latest + margin)
    } else {
        (0.0, 1.0)
    };
    let (w, h) = (900u32, 520u32);
    let mut buf = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE)?;
        let title = if top.is_finite() {
            format!("Power-delay profile at {receiver}")
        } else {
            format!("Power-delay profile at {receiver}: no path")
        };
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 18))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(x0..x1, y0..y1)?;
        chart
            .configure_mesh()
            .x_desc("delay (ns)")
            .y_desc("path gain (dB)")
            .y_label_formatter(&|v| format!("{v:.0}"))
            .label_style(("sans-serif", 13))
            .draw()?;
        for (i, (name, points)) in transmitters.iter().enumerate() {
            let colour = transmitter_colour(i);
            let style = colour.stroke_width(2);
            chart
                .draw_series(
                    points.iter().map(|&(x, y)| PathElement::new(vec![(x, y0), (x, y.max(y0))], style)),
                )?
                .label(name.clone())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2)));
            chart.draw_series(points.iter().map(|&(x, y)| Circle::new((x, y.max(y0)), 4, style)))?;
        }
        if transmitters.len() > 1 {
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .label_font(("sans-serif", 13))
                .draw()?;
        }
        root.present()?;
    }
    write_rgb_png(path, w, h, &buf)
}
