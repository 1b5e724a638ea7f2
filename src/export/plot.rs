//! Line charts with a logarithmic y axis, drawn on the CPU into a PNG (for `isomesh bench`).
//! Several panels sit side by side in one picture.

use std::path::Path;

use super::raster;
use crate::error::{Error, Result};

/// One line of a chart: a name for the legend, a colour, and (x, y) points (y > 0; others
/// are left out).
#[derive(Clone, Debug)]
pub struct Series {
    /// Legend text.
    pub name: String,
    /// RGB colour.
    pub color: [u8; 3],
    /// The points, drawn in order.
    pub points: Vec<(f64, f64)>,
}

/// One panel: a title, axis labels, and its lines. The x axis is linear; when `x_ticks` is
/// given, it labels those x positions with text instead of numbers.
#[derive(Clone, Debug, Default)]
pub struct Chart {
    /// Title above the panel.
    pub title: String,
    /// Label under the x axis.
    pub x_label: String,
    /// Label of the (logarithmic) y axis.
    pub y_label: String,
    /// The lines.
    pub series: Vec<Series>,
    /// Text labels at x positions (empty: numeric ticks at the points' x values).
    pub x_ticks: Vec<(f64, String)>,
}

/// Colours that read well on white, for successive series.
pub const PALETTE: [[u8; 3]; 5] = [
    [31, 119, 180],
    [214, 39, 40],
    [44, 160, 44],
    [148, 103, 189],
    [255, 127, 14],
];

struct Canvas {
    width: usize,
    height: usize,
    rgb: Vec<u8>,
}

impl Canvas {
    fn put(&mut self, x: isize, y: isize, col: [u8; 3]) {
        if x >= 0 && y >= 0 && (x as usize) < self.width && (y as usize) < self.height {
            let i = (y as usize * self.width + x as usize) * 3;
            self.rgb[i..i + 3].copy_from_slice(&col);
        }
    }

    fn rect(&mut self, (x0, y0): (f64, f64), (x1, y1): (f64, f64), col: [u8; 3]) {
        for y in y0.round() as isize..=y1.round() as isize {
            for x in x0.round() as isize..=x1.round() as isize {
                self.put(x, y, col);
            }
        }
    }

    fn line(&mut self, a: (f64, f64), b: (f64, f64), thick: isize, col: [u8; 3]) {
        let steps = ((b.0 - a.0).abs().max((b.1 - a.1).abs()).ceil() as usize).max(1);
        for s in 0..=steps {
            let t = s as f64 / steps as f64;
            let (x, y) = (a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1));
            for dy in -(thick / 2)..=thick / 2 {
                for dx in -(thick / 2)..=thick / 2 {
                    self.put(x.round() as isize + dx, y.round() as isize + dy, col);
                }
            }
        }
    }

    fn text(&mut self, x: f64, y: f64, s: &str, col: [u8; 3]) {
        let (x, y) = (x.max(0.0) as usize, y.max(0.0) as usize);
        raster::text(&mut self.rgb, self.width, self.height, (x, y), s, col);
    }
}

/// Draws `charts` side by side, each `panel` = (width, height) pixels, into a PNG at `path`.
pub fn write_charts(path: &Path, charts: &[Chart], panel: (usize, usize)) -> Result<()> {
    if charts.is_empty() || panel.0 < 200 || panel.1 < 150 {
        return Err(Error::Output(format!(
            "{}: nothing to plot, or panels under 200x150",
            path.display()
        )));
    }
    let mut c = Canvas {
        width: panel.0 * charts.len(),
        height: panel.1,
        rgb: vec![255; panel.0 * charts.len() * panel.1 * 3],
    };
    for (i, chart) in charts.iter().enumerate() {
        draw(&mut c, chart, (i * panel.0) as f64, panel);
    }
    raster::write_png(path, c.width, c.height, &c.rgb)
}

fn draw(c: &mut Canvas, chart: &Chart, left: f64, (w, h): (usize, usize)) {
    const INK: [u8; 3] = [30, 30, 30];
    const GRID: [u8; 3] = [225, 225, 225];
    let (w, h) = (w as f64, h as f64);
    let (x0, x1, y0, y1) = (left + 90.0, left + w - 20.0, h - 60.0, 68.0);
    c.text(left + 20.0, 12.0, &chart.title, INK);
    let pts = || {
        chart
            .series
            .iter()
            .flat_map(|s| s.points.iter().copied())
            .filter(|p| p.1 > 0.0 && p.0.is_finite() && p.1.is_finite())
    };
    let (mut xmin, mut xmax) = (f64::INFINITY, f64::NEG_INFINITY);
    let (mut lmin, mut lmax) = (f64::INFINITY, f64::NEG_INFINITY);
    for (x, y) in pts() {
        xmin = xmin.min(x);
        xmax = xmax.max(x);
        lmin = lmin.min(y.log10().floor());
        lmax = lmax.max(y.log10().ceil());
    }
    if !xmin.is_finite() {
        c.text(x0, (y0 + y1) / 2.0, "no data", INK);
        return;
    }
    if xmax - xmin < 1e-9 {
        xmin -= 1.0;
        xmax += 1.0;
    }
    let pad = 0.05 * (xmax - xmin);
    let (xmin, xmax) = (xmin - pad, xmax + pad);
    if lmax <= lmin {
        lmax = lmin + 1.0;
    }
    let sx = |x: f64| x0 + (x - xmin) / (xmax - xmin) * (x1 - x0);
    let sy = |y: f64| y0 - (y.log10() - lmin) / (lmax - lmin) * (y0 - y1);
    // Grid and y labels at every power of ten.
    for e in lmin as i32..=lmax as i32 {
        let y = sy(10f64.powi(e));
        c.line((x0, y), (x1, y), 1, GRID);
        c.text(left + 30.0, y - 8.0, &format!("1e{e}"), INK);
    }
    // x ticks.
    let ticks: Vec<(f64, String)> = if chart.x_ticks.is_empty() {
        let mut xs: Vec<f64> = pts().map(|p| p.0).collect();
        xs.sort_by(f64::total_cmp);
        xs.dedup();
        xs.into_iter().map(|x| (x, format!("{x}"))).collect()
    } else {
        chart.x_ticks.clone()
    };
    for (x, label) in &ticks {
        let px = sx(*x);
        c.line((px, y0), (px, y0 + 5.0), 1, INK);
        let tw = raster::text_width(label) as f64;
        c.text(px - tw / 2.0, y0 + 8.0, label, INK);
    }
    c.line((x0, y0), (x1, y0), 1, INK);
    c.line((x0, y0), (x0, y1), 1, INK);
    c.text(
        (x0 + x1) / 2.0 - raster::text_width(&chart.x_label) as f64 / 2.0,
        h - 26.0,
        &chart.x_label,
        INK,
    );
    c.text(left + 20.0, 30.0, &chart.y_label, INK);
    // Lines with square markers, then the legend.
    for (i, s) in chart.series.iter().enumerate() {
        let p: Vec<(f64, f64)> = s
            .points
            .iter()
            .filter(|p| p.1 > 0.0 && p.1.is_finite())
            .map(|&(x, y)| (sx(x), sy(y)))
            .collect();
        for pair in p.windows(2) {
            c.line(pair[0], pair[1], 3, s.color);
        }
        for &(x, y) in &p {
            c.rect((x - 4.0, y - 4.0), (x + 4.0, y + 4.0), s.color);
        }
        let ly = y1 + 8.0 + 20.0 * i as f64;
        c.rect((x1 - 190.0, ly + 3.0), (x1 - 176.0, ly + 11.0), s.color);
        c.text(x1 - 170.0, ly, &s.name, INK);
    }
}
