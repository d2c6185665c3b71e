//! PNG figures for the benchmarks: line charts (optionally log-log) and labelled contact
//! sheets. Text uses the embedded DejaVu Sans, so figures look the same on every machine.

use std::path::Path;
use std::sync::Once;

use anyhow::{Result, anyhow};
use plotters::prelude::*;
use plotters::style::FontStyle;

use crate::imaging::{RgbImage, to_srgb8, write_atomically};

static FONT: Once = Once::new();

fn register_font() {
    FONT.call_once(|| {
        let bytes: &'static [u8] = include_bytes!("fonts/DejaVuSans.ttf");
        // Cannot fail for a valid TrueType file; a failure would only leave text out.
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, bytes);
    });
}

/// One line on a chart.
#[derive(Clone, Debug)]
pub struct Series {
    pub label: String,
    pub points: Vec<(f64, f64)>,
}

#[derive(Clone, Debug)]
pub struct Chart {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub log_x: bool,
    pub log_y: bool,
}

const PALETTE: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
];

fn save_rgb8(path: &Path, buf: &[u8], w: u32, h: u32) -> Result<()> {
    write_atomically(path, |tmp| {
        image::save_buffer_with_format(
            tmp,
            buf,
            w,
            h,
            image::ColorType::Rgb8,
            image::ImageFormat::Png,
        )
        .map_err(|e| anyhow!("encoding PNG: {e}"))
    })
}

fn range(values: impl Iterator<Item = f64>, log: bool) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values.filter(|v| v.is_finite() && (!log || *v > 0.0)) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !lo.is_finite() {
        return (1.0, 10.0);
    }
    if log {
        (lo / 1.5, hi * 1.5)
    } else {
        let pad = ((hi - lo) * 0.05).max(1e-9);
        (lo - pad, hi + pad)
    }
}

/// A line chart with markers, one line per series.
pub fn line_chart(path: &Path, chart: &Chart, series: &[Series]) -> Result<()> {
    register_font();
    let (w, h) = (900u32, 600u32);
    let mut buf = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| anyhow!("{e}"))?;
        draw_chart(&root, chart, series, 22)?;
        root.present().map_err(|e| anyhow!("{e}"))?;
    }
    save_rgb8(path, &buf, w, h)
}

/// Several line charts in one figure, `columns` per row under a common title: one panel per
/// condition (e.g. resolution) when one chart with every condition's lines would repeat the
/// palette. A series keeps its colour across panels when it keeps its index.
pub fn panel_chart(
    path: &Path,
    title: &str,
    columns: usize,
    panels: &[(Chart, Vec<Series>)],
) -> Result<()> {
    register_font();
    let columns = columns.max(1);
    let rows = panels.len().div_ceil(columns).max(1);
    let (pw, ph, head) = (640u32, 440u32, 40u32);
    let (w, h) = (pw * columns as u32, ph * rows as u32 + head);
    let mut buf = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| anyhow!("{e}"))?;
        let body = root
            .titled(title, ("sans-serif", 24))
            .map_err(|e| anyhow!("{e}"))?;
        let areas = body.split_evenly((rows, columns));
        for ((chart, series), area) in panels.iter().zip(&areas) {
            draw_chart(area, chart, series, 18)?;
        }
        root.present().map_err(|e| anyhow!("{e}"))?;
    }
    save_rgb8(path, &buf, w, h)
}

/// Draws one chart (axes, lines with markers, legend) into `area`.
fn draw_chart(
    area: &DrawingArea<BitMapBackend<'_>, plotters::coord::Shift>,
    chart: &Chart,
    series: &[Series],
    caption_size: u32,
) -> Result<()> {
    let xs = range(
        series.iter().flat_map(|s| s.points.iter().map(|p| p.0)),
        chart.log_x,
    );
    let ys = range(
        series.iter().flat_map(|s| s.points.iter().map(|p| p.1)),
        chart.log_y,
    );
    let mut builder = ChartBuilder::on(area);
    builder
        .caption(&chart.title, ("sans-serif", caption_size))
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(70);
    macro_rules! draw {
        ($ctx:expr) => {{
            let mut ctx = $ctx;
            ctx.configure_mesh()
                .x_desc(chart.x_label.as_str())
                .y_desc(chart.y_label.as_str())
                .label_style(("sans-serif", 14))
                .draw()
                .map_err(|e| anyhow!("{e}"))?;
            for (i, s) in series.iter().enumerate() {
                let color = PALETTE[i % PALETTE.len()];
                let pts: Vec<(f64, f64)> = s
                    .points
                    .iter()
                    .copied()
                    .filter(|p| {
                        p.0.is_finite()
                            && p.1.is_finite()
                            && (!chart.log_x || p.0 > 0.0)
                            && (!chart.log_y || p.1 > 0.0)
                    })
                    .collect();
                ctx.draw_series(LineSeries::new(pts.clone(), color.stroke_width(2)))
                    .map_err(|e| anyhow!("{e}"))?
                    .label(s.label.as_str())
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
                    });
                ctx.draw_series(pts.into_iter().map(|p| Circle::new(p, 3, color.filled())))
                    .map_err(|e| anyhow!("{e}"))?;
            }
            ctx.configure_series_labels()
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .label_font(("sans-serif", 14))
                .draw()
                .map_err(|e| anyhow!("{e}"))?;
        }};
    }
    match (chart.log_x, chart.log_y) {
        (true, true) => draw!(
            builder
                .build_cartesian_2d((xs.0..xs.1).log_scale(), (ys.0..ys.1).log_scale())
                .map_err(|e| anyhow!("{e}"))?
        ),
        (true, false) => draw!(
            builder
                .build_cartesian_2d((xs.0..xs.1).log_scale(), ys.0..ys.1)
                .map_err(|e| anyhow!("{e}"))?
        ),
        (false, true) => draw!(
            builder
                .build_cartesian_2d(xs.0..xs.1, (ys.0..ys.1).log_scale())
                .map_err(|e| anyhow!("{e}"))?
        ),
        (false, false) => draw!(
            builder
                .build_cartesian_2d(xs.0..xs.1, ys.0..ys.1)
                .map_err(|e| anyhow!("{e}"))?
        ),
    }
    Ok(())
}

/// Images side by side in rows of `columns`, each with a caption under it; tone-mapped at
/// `exposure` like the PNG output.
pub fn contact_sheet(
    path: &Path,
    tiles: &[(String, &RgbImage)],
    columns: usize,
    exposure: f32,
) -> Result<()> {
    register_font();
    let columns = columns.max(1);
    let tw = tiles.iter().map(|t| t.1.width).max().unwrap_or(1);
    let th = tiles.iter().map(|t| t.1.height).max().unwrap_or(1);
    let caption = 26u32;
    let rows = tiles.len().div_ceil(columns) as u32;
    let (w, h) = (tw * columns as u32, (th + caption) * rows.max(1));
    let mut buf = vec![255u8; (w * h * 3) as usize];
    for (i, (_, img)) in tiles.iter().enumerate() {
        let (cx, cy) = (
            (i % columns) as u32 * tw,
            (i / columns) as u32 * (th + caption),
        );
        let srgb = to_srgb8(img, exposure);
        for y in 0..img.height {
            let src = &srgb[(y * img.width * 3) as usize..((y + 1) * img.width * 3) as usize];
            let dst = (((cy + y) * w + cx) * 3) as usize;
            buf[dst..dst + src.len()].copy_from_slice(src);
        }
    }
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        for (i, (label, _)) in tiles.iter().enumerate() {
            let (cx, cy) = (
                (i % columns) as u32 * tw,
                (i / columns) as u32 * (th + caption) + th,
            );
            root.draw_text(
                label,
                &("sans-serif", 16).into_font().color(&BLACK),
                (cx as i32 + 4, cy as i32 + 4),
            )
            .map_err(|e| anyhow!("{e}"))?;
        }
        root.present().map_err(|e| anyhow!("{e}"))?;
    }
    save_rgb8(path, &buf, w, h)
}

/// Halves an image in each dimension (2x2 box filter), for small contact sheets.
pub fn half_size(img: &RgbImage) -> RgbImage {
    let (w, h) = ((img.width / 2).max(1), (img.height / 2).max(1));
    let mut pixels = Vec::with_capacity((w * h) as usize);
    for y in 0..h {
        for x in 0..w {
            let mut acc = [0.0f32; 3];
            let mut n = 0.0;
            for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                let (sx, sy) = (2 * x + dx, 2 * y + dy);
                if sx < img.width && sy < img.height {
                    let p = img.pixels[(sy * img.width + sx) as usize];
                    for c in 0..3 {
                        acc[c] += p[c];
                    }
                    n += 1.0;
                }
            }
            pixels.push(acc.map(|v| v / n));
        }
    }
    RgbImage {
        width: w,
        height: h,
        pixels,
    }
}
