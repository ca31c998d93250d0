//! Charts drawn with plotters into an RGB buffer and written as PNG. Text uses DejaVu Sans,
//! shipped in `assets/fonts` with its licence (no system fonts needed).

use std::path::Path;
use std::sync::Once;

use plotters::coord::Shift;
use plotters::element::DashedPathElement;
use plotters::prelude::*;
use plotters::style::FontStyle;

static FONT: Once = Once::new();
const FONT_BYTES: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");

/// Makes "sans-serif" available to plotters (once per process).
pub fn register_font() {
    FONT.call_once(|| {
        // The font is compiled in and known to parse; a failure would only lose the text.
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT_BYTES);
    });
}

/// Writes an 8-bit RGB buffer as PNG.
pub fn write_rgb_png(path: &Path, width: u32, height: u32, rgb: &[u8]) -> anyhow::Result<()> {
    super::atomic::write_atomically(path, |w| {
        let mut enc = png::Encoder::new(w, width, height);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut writer = enc.write_header()?;
        writer.write_image_data(rgb)?;
        writer.finish()?;
        Ok(())
    })
}

/// One line of a chart.
#[derive(Clone, Debug, Default)]
pub struct Series {
    /// Legend text.
    pub label: String,
    /// Points `(x, y)`.
    pub points: Vec<(f64, f64)>,
    /// Drawn dashed (e.g. data extrapolated rather than given).
    pub dashed: bool,
    /// Points marked with a circle on the line (e.g. where a decay curve was truncated).
    pub markers: Vec<(f64, f64)>,
}

impl Series {
    /// A solid line without markers.
    pub fn new(label: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        Self { label: label.into(), points, ..Self::default() }
    }
}

/// Titles and axis ranges of a line chart.
#[derive(Clone, Copy, Debug)]
pub struct Chart<'a> {
    /// Chart title.
    pub title: &'a str,
    /// Label of the x axis.
    pub x_label: &'a str,
    /// Label of the y axis.
    pub y_label: &'a str,
    /// Range of the x axis.
    pub x_range: (f64, f64),
    /// Range of the y axis.
    pub y_range: (f64, f64),
    /// Legend text for the circle markers, shown when a series has markers.
    pub marker_label: Option<&'a str>,
}

/// Distinct colours for up to eight series (Okabe & Ito 2008, colour-blind safe, plus grey):
/// chart series, and the transmitters on radio maps.
pub(crate) const PALETTE: [RGBColor; 8] = [
    RGBColor(0, 114, 178),
    RGBColor(230, 159, 0),
    RGBColor(0, 158, 115),
    RGBColor(213, 94, 0),
    RGBColor(86, 180, 233),
    RGBColor(204, 121, 167),
    RGBColor(120, 120, 120),
    RGBColor(0, 0, 0),
];

/// Dash and gap lengths of dashed series, pixels.
const DASH_PX: u32 = 12;
const GAP_PX: u32 = 7;
/// Width of the legend panel beside the plot when there are several series, pixels.
const LEGEND_WIDTH_PX: u32 = 190;

/// A line chart of `series` as PNG. With more than one series the legend stands in a panel to
/// the right of the plot, so it never hides a curve.
pub fn line_chart(path: &Path, chart: &Chart, series: &[Series]) -> anyhow::Result<()> {
    register_font();
    let legend = series.len() > 1;
    let (w, h) = (if legend { 900 + LEGEND_WIDTH_PX } else { 900u32 }, 520u32);
    let mut buf = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE)?;
        let (plot_area, legend_area) = root.split_horizontally(w - if legend { LEGEND_WIDTH_PX } else { 0 });
        let (x0, x1) = chart.x_range;
        let (y0, y1) = chart.y_range;
        let mut ctx = ChartBuilder::on(&plot_area)
            .caption(chart.title, ("sans-serif", 18))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(x0..x1, y0..y1)?;
        // Whole numbers on an axis that spans 10 units or more (dB scales).
        let y_digits = if y1 - y0 >= 10.0 { 0 } else { 2 };
        ctx.configure_mesh()
            .x_desc(chart.x_label)
            .y_desc(chart.y_label)
            .y_label_formatter(&|v| format!("{v:.y_digits$}"))
            .label_style(("sans-serif", 13))
            .draw()?;
        // Dashed series last, so that a dashed curve lying on a solid one stays visible.
        let order = series
            .iter()
            .enumerate()
            .filter(|(_, s)| !s.dashed)
            .chain(series.iter().enumerate().filter(|(_, s)| s.dashed));
        for (i, s) in order {
            let style = PALETTE[i % PALETTE.len()].stroke_width(2);
            if s.dashed {
                ctx.draw_series(DashedLineSeries::new(s.points.iter().copied(), DASH_PX, GAP_PX, style))?;
            } else {
                ctx.draw_series(LineSeries::new(s.points.iter().copied(), style))?;
            }
            ctx.draw_series(s.markers.iter().map(|&p| Circle::new(p, 5, style)))?;
        }
        if legend {
            draw_legend(&legend_area, chart, series)?;
        }
        root.present()?;
    }
    write_rgb_png(path, w, h, &buf)
}

/// The legend panel: a line sample and the label of every series, then the marker's meaning.
fn draw_legend(
    area: &DrawingArea<BitMapBackend, Shift>,
    chart: &Chart,
    series: &[Series],
) -> anyhow::Result<()> {
    let font = ("sans-serif", 13).into_font().color(&BLACK);
    let row = 22;
    let top = 48;
    let (x_line, x_text) = (8, 44);
    for (i, s) in series.iter().enumerate() {
        let style = PALETTE[i % PALETTE.len()].stroke_width(2);
        let y = top + row * i as i32;
        let sample = vec![(x_line, y), (x_line + 28, y)];
        if s.dashed {
            area.draw(&DashedPathElement::new(sample, DASH_PX - 2, GAP_PX - 1, style))?;
        } else {
            area.draw(&PathElement::new(sample, style))?;
        }
        area.draw(&Text::new(s.label.clone(), (x_text, y - 7), font.clone()))?;
    }
    if let Some(label) = chart.marker_label.filter(|_| series.iter().any(|s| !s.markers.is_empty())) {
        let y = top + row * series.len() as i32 + 8;
        area.draw(&Circle::new((x_line + 14, y), 5, BLACK.stroke_width(2)))?;
        area.draw(&Text::new(label.to_string(), (x_text, y - 7), font))?;
    }
    Ok(())
}
