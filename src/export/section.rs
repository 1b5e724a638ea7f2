//! The section of a 3-manifold complex by a hyperplane of R^d: a closed polygon per 3-cell
//! that the hyperplane cuts, whose corners are the points where it cuts the 1-cells. Pictures
//! draw it, since every edge of a closed 3-manifold seen at once is a solid blob.
//!
//! A vertex is on the positive side when `<n, x> >= c`, so no vertex lies on the hyperplane
//! and the section is that of a hyperplane moved by an infinitesimal amount. A 1-cell is cut
//! where its two vertices' sides differ; a 2-cell (a convex polygon) where two of its 1-cells
//! are, and the cut is the segment between their points; a 3-cell's segments close into one
//! polygon. The corners are combinatorial, shared between neighbouring polygons: the
//! section of a closed 3-manifold by such a hyperplane is a closed surface.

use crate::complex::Complex;
use crate::error::{Error, Result};
use crate::linalg::symmetric_eigen;

/// Polygons in R^d: the section of a complex by a hyperplane.
#[derive(Clone, Debug, Default)]
pub struct Section {
    /// Ambient dimension d.
    pub dim: usize,
    /// Corner points, d coordinates each.
    pub points: Vec<f64>,
    /// Each polygon's corners in order (indices into the points).
    pub polygons: Vec<Vec<u32>>,
    /// Cut 2-cells and 3-cells whose cut was not one segment or one closed polygon
    /// (non-convex clipped cells at the domain's boundary); they are left out.
    pub skipped: usize,
}

impl Section {
    /// The section of the 3-cells of `c` by `{x : <normal, x> = offset}`; an error when the
    /// normal has not d coordinates.
    pub fn of(c: &Complex, normal: &[f64], offset: f64) -> Result<Section> {
        let d = c.ambient_dim();
        if normal.len() != d {
            return Err(Error::DimensionMismatch(format!(
                "a section normal has {} coordinates, the complex lies in R^{d}",
                normal.len()
            )));
        }
        let pts = c.points();
        let height: Vec<f64> = pts
            .chunks_exact(d)
            .map(|x| x.iter().zip(normal).map(|(a, b)| a * b).sum::<f64>() - offset)
            .collect();
        let mut out = Section {
            dim: d,
            ..Section::default()
        };
        if c.dim() < 3 {
            return Ok(out);
        }
        // 1-cells: the point where each cut one is crossed.
        let edges = c.level(1);
        let mut corner = vec![u32::MAX; edges.len()];
        for (e, slot) in corner.iter_mut().enumerate() {
            if let [a, b] = *edges.facets(e) {
                let (ha, hb) = (height[a as usize], height[b as usize]);
                if (ha >= 0.0) != (hb >= 0.0) {
                    let t = ha / (ha - hb);
                    let (pa, pb) = (a as usize * d, b as usize * d);
                    *slot = (out.points.len() / d) as u32;
                    for i in 0..d {
                        out.points
                            .push(pts[pa + i] + t * (pts[pb + i] - pts[pa + i]));
                    }
                }
            }
        }
        // 2-cells: the segment between their two cut 1-cells.
        let faces = c.level(2);
        let mut segment = vec![[u32::MAX; 2]; faces.len()];
        for (f, seg) in segment.iter_mut().enumerate() {
            let mut cut = faces.facets(f).iter().map(|&e| corner[e as usize]);
            let mut ends = cut.by_ref().filter(|&p| p != u32::MAX);
            match (ends.next(), ends.next(), ends.next()) {
                (None, ..) => {}
                (Some(p), Some(q), None) => *seg = [p, q],
                _ => out.skipped += 1,
            }
        }
        // 3-cells: their segments chained into a closed polygon.
        let cells = c.level(3);
        let mut segs: Vec<[u32; 2]> = Vec::new();
        for i in 0..cells.len() {
            segs.clear();
            segs.extend(
                cells
                    .facets(i)
                    .iter()
                    .map(|&f| segment[f as usize])
                    .filter(|s| s[0] != u32::MAX),
            );
            if segs.is_empty() {
                continue;
            }
            match chain(&segs) {
                Some(polygon) => out.polygons.push(polygon),
                None => out.skipped += 1,
            }
        }
        Ok(out)
    }

    /// The section by the hyperplane through the centroid of `c`'s vertices, normal to the
    /// direction along which they vary least (the last principal axis).
    pub fn through_centroid(c: &Complex) -> Section {
        let d = c.ambient_dim();
        let (centre, axes) = principal_axes(c.points(), d);
        let normal = &axes[(d - 1) * d..];
        let offset = normal.iter().zip(&centre).map(|(a, b)| a * b).sum();
        Section::of(c, normal, offset).expect("a normal of R^d")
    }

    /// The polygons as fan triangles.
    pub fn triangles(&self) -> Vec<[u32; 3]> {
        self.polygons
            .iter()
            .flat_map(|p| (1..p.len() - 1).map(move |i| [p[0], p[i], p[i + 1]]))
            .collect()
    }
}

/// `segs` joined end to end into one closed polygon, or `None` when they do not form one.
fn chain(segs: &[[u32; 2]]) -> Option<Vec<u32>> {
    if segs.len() < 3 {
        return None;
    }
    let mut used = vec![false; segs.len()];
    let mut polygon = vec![segs[0][0]];
    let mut at = segs[0][1];
    used[0] = true;
    while at != polygon[0] {
        polygon.push(at);
        let next = (0..segs.len()).find(|&j| !used[j] && segs[j].contains(&at))?;
        used[next] = true;
        at = if segs[next][0] == at {
            segs[next][1]
        } else {
            segs[next][0]
        };
    }
    used.iter().all(|&u| u).then_some(polygon)
}

/// The centroid of `points` (d each) and the principal axes of their spread, as the rows of
/// a d x d matrix in decreasing order of variance.
pub fn principal_axes(points: &[f64], d: usize) -> (Vec<f64>, Vec<f64>) {
    let n = (points.len() / d).max(1) as f64;
    let mut centre = vec![0.0; d];
    for x in points.chunks_exact(d) {
        for (c, v) in centre.iter_mut().zip(x) {
            *c += v / n;
        }
    }
    let mut cov = vec![0.0; d * d];
    for x in points.chunks_exact(d) {
        for i in 0..d {
            for j in 0..d {
                cov[i * d + j] += (x[i] - centre[i]) * (x[j] - centre[j]) / n;
            }
        }
    }
    let (_, vectors) = symmetric_eigen(&cov, d);
    (centre, vectors)
}
