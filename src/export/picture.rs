//! PNG pictures of a mesh, drawn on the CPU: surfaces as lit triangles with a depth buffer,
//! curves as lines, seen obliquely in the mesh's 3-D view, with a caption that says how R^d
//! was seen. A 3-manifold with boundary is drawn as its boundary; a closed one as its
//! [`Section`] by the hyperplane through its centre, normal to its least-varying axis (every
//! edge at once is a solid blob).

use std::borrow::Cow;
use std::path::Path;

use super::mesh::Mesh;
use super::projection::{Projection, View};
use super::section::Section;
use crate::error::{Error, Result};

/// An RGB picture.
pub struct Picture {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Rows of RGB bytes, top first.
    pub rgb: Vec<u8>,
    depth: Vec<f32>,
}

/// Where the camera looks from (a unit vector towards the viewer) and the up direction.
const EYE: [f64; 3] = [0.55, -0.65, 0.52];
const UP: [f64; 3] = [0.0, 0.0, 1.0];
/// Light directions (towards the light) in camera space: key and fill.
const KEY: [f64; 3] = [-0.4, 0.6, 0.7];
const FILL: [f64; 3] = [0.6, -0.2, 0.75];

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn unit(a: [f64; 3]) -> [f64; 3] {
    let l = dot(a, a).sqrt();
    if l > 0.0 {
        [a[0] / l, a[1] / l, a[2] / l]
    } else {
        a
    }
}

/// The sides a picture may have, in pixels.
pub const SIDES: std::ops::RangeInclusive<usize> = 64..=8192;

impl Picture {
    /// Draws `mesh` at `width` x `height` with `caption` under it, and above it how R^d was
    /// seen when that is not its coordinates ("PCA view", "section by a hyperplane...").
    pub fn render(mesh: &Mesh, width: usize, height: usize, caption: &str) -> Result<Self> {
        if !SIDES.contains(&width) || !SIDES.contains(&height) {
            return Err(Error::Output(format!(
                "picture size {width}x{height}: each side must be {} to {} pixels",
                SIDES.start(),
                SIDES.end()
            )));
        }
        let mut pic = Picture {
            width,
            height,
            rgb: vec![0; width * height * 3],
            depth: vec![f32::INFINITY; width * height],
        };
        for y in 0..height {
            let t = y as f64 / height as f64;
            let c = [248.0 - 30.0 * t, 250.0 - 26.0 * t, 255.0 - 18.0 * t];
            for x in 0..width {
                pic.rgb[(y * width + x) * 3..][..3].copy_from_slice(&c.map(|v| v as u8));
            }
        }
        let c = mesh.complex;
        let (d, m) = (c.ambient_dim(), c.dim());
        let section = (m == 3 && mesh.triangles.is_empty()).then(|| Section::through_centroid(c));
        let (xyz, triangles, seen) = match &section {
            Some(s) => {
                let view = View::new(&Projection::Auto, &s.points, d);
                (
                    Cow::Owned(view.apply_all(&s.points)),
                    Cow::Owned(s.triangles()),
                    "section by a hyperplane; PCA view",
                )
            }
            None => (
                Cow::Borrowed(&mesh.xyz[..]),
                Cow::Borrowed(&mesh.triangles[..]),
                if mesh.view.description.starts_with("pca") {
                    "PCA view"
                } else {
                    ""
                },
            ),
        };
        // Two colours for the two sides of an oriented surface in R^3; seen from R^d, d > 3,
        // a projection folds, and both sides are drawn alike.
        let two_sided = m == 2 && d <= 3 && section.is_none();
        // Camera frame: right, up, towards the viewer.
        let fwd = unit(EYE);
        let right = unit(cross(UP, fwd));
        let up = cross(fwd, right);
        let n = xyz.len() / 3;
        let cam: Vec<[f64; 3]> = (0..n)
            .map(|i| {
                let p = [xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]];
                [dot(p, right), dot(p, up), dot(p, fwd)]
            })
            .collect();
        let caption_h = 28.0;
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in &cam {
            for a in 0..2 {
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
        }
        let margin = 0.06 * width.min(height) as f64;
        let (w, h) = (width as f64, height as f64 - caption_h);
        let scale = ((w - 2.0 * margin) / (hi[0] - lo[0]).max(1e-12))
            .min((h - 2.0 * margin) / (hi[1] - lo[1]).max(1e-12));
        let (cx, cy) = (0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]));
        let screen: Vec<[f64; 3]> = cam
            .iter()
            .map(|p| {
                [
                    0.5 * w + (p[0] - cx) * scale,
                    0.5 * h - (p[1] - cy) * scale,
                    -p[2],
                ]
            })
            .collect();
        if !triangles.is_empty() {
            for t in triangles.iter() {
                let [a, b, c] = t.map(|v| cam[v as usize]);
                let raw = unit(cross(
                    [b[0] - a[0], b[1] - a[1], b[2] - a[2]],
                    [c[0] - a[0], c[1] - a[1], c[2] - a[2]],
                ));
                // Two-sided: the side facing the viewer is lit; an oriented surface shows
                // its back side in another colour.
                let front = !two_sided || raw[2] >= 0.0;
                let nrm = if raw[2] < 0.0 { raw.map(|x| -x) } else { raw };
                let light = 0.22
                    + 0.62 * dot(nrm, unit(KEY)).max(0.0)
                    + 0.25 * dot(nrm, unit(FILL)).max(0.0);
                let spec = dot(nrm, unit([KEY[0], KEY[1], KEY[2] + 1.0]))
                    .max(0.0)
                    .powi(24);
                let base = if front {
                    [0.36, 0.56, 0.86]
                } else {
                    [0.9, 0.55, 0.3]
                };
                let col = base.map(|b| ((b * light + 0.35 * spec).min(1.0) * 255.0) as u8);
                pic.triangle(t.map(|v| screen[v as usize]), col);
            }
        } else {
            let edges = mesh.complex.level(1);
            let (zlo, zhi) = screen
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
                    (a.min(p[2]), b.max(p[2]))
                });
            let thick = if m == 1 { 2.0 } else { 1.0 };
            for i in 0..edges.len() {
                if let [a, b] = edges.facets(i) {
                    let (pa, pb) = (screen[*a as usize], screen[*b as usize]);
                    let t = (0.5 * (pa[2] + pb[2]) - zlo) / (zhi - zlo).max(1e-12);
                    let shade = (40.0 + 150.0 * t) as u8;
                    let col = if m == 1 {
                        [shade / 3, shade / 2 + 20, 140 + shade / 2]
                    } else {
                        [shade, shade, shade + 40]
                    };
                    pic.line(pa, pb, thick, col);
                }
            }
        }
        pic.text(8, height - 20, caption, [30, 34, 44]);
        pic.text(8, 6, seen, [70, 76, 96]);
        Ok(pic)
    }

    fn triangle(&mut self, v: [[f64; 3]; 3], col: [u8; 3]) {
        let area =
            (v[1][0] - v[0][0]) * (v[2][1] - v[0][1]) - (v[2][0] - v[0][0]) * (v[1][1] - v[0][1]);
        if area.abs() < 1e-12 {
            return;
        }
        let x0 = v
            .iter()
            .map(|p| p[0])
            .fold(f64::INFINITY, f64::min)
            .floor()
            .max(0.0) as usize;
        let x1 = (v
            .iter()
            .map(|p| p[0])
            .fold(f64::NEG_INFINITY, f64::max)
            .ceil() as usize)
            .min(self.width - 1);
        let y0 = v
            .iter()
            .map(|p| p[1])
            .fold(f64::INFINITY, f64::min)
            .floor()
            .max(0.0) as usize;
        let y1 = (v
            .iter()
            .map(|p| p[1])
            .fold(f64::NEG_INFINITY, f64::max)
            .ceil() as usize)
            .min(self.height - 1);
        for y in y0..=y1 {
            for x in x0..=x1 {
                let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
                let e = |a: [f64; 3], b: [f64; 3]| {
                    (b[0] - a[0]) * (py - a[1]) - (b[1] - a[1]) * (px - a[0])
                };
                let w0 = e(v[1], v[2]) / area;
                let w1 = e(v[2], v[0]) / area;
                let w2 = e(v[0], v[1]) / area;
                if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                    continue;
                }
                let z = (w0 * v[0][2] + w1 * v[1][2] + w2 * v[2][2]) as f32;
                self.plot(x, y, z, col);
            }
        }
    }

    fn line(&mut self, a: [f64; 3], b: [f64; 3], thick: f64, col: [u8; 3]) {
        let steps = ((b[0] - a[0]).abs().max((b[1] - a[1]).abs()).ceil() as usize).max(1);
        let r = (thick.round() as isize).max(1);
        for s in 0..=steps {
            let t = s as f64 / steps as f64;
            let x = a[0] + t * (b[0] - a[0]);
            let y = a[1] + t * (b[1] - a[1]);
            let z = (a[2] + t * (b[2] - a[2])) as f32;
            for dy in 0..r {
                for dx in 0..r {
                    let (px, py) = (x as isize + dx, y as isize + dy);
                    if px >= 0 && py >= 0 {
                        self.plot(px as usize, py as usize, z, col);
                    }
                }
            }
        }
    }

    fn plot(&mut self, x: usize, y: usize, z: f32, col: [u8; 3]) {
        if x >= self.width || y >= self.height {
            return;
        }
        let i = y * self.width + x;
        if z <= self.depth[i] {
            self.depth[i] = z;
            self.rgb[i * 3..i * 3 + 3].copy_from_slice(&col);
        }
    }

    fn text(&mut self, x: usize, y: usize, text: &str, col: [u8; 3]) {
        super::raster::text(&mut self.rgb, self.width, self.height, (x, y), text, col);
    }

    /// Encodes the picture as PNG into `path` (through a temporary file).
    pub fn write_png(&self, path: &Path) -> Result<()> {
        super::raster::write_png(path, self.width, self.height, &self.rgb)
    }
}
