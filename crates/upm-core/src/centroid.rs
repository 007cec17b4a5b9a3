//! Coverage centroids of parts in image windows: the inner loop of vision's part refinement and
//! tracking (`upm.vision`), where it runs for every part of every camera frame.
//!
//! Each part `i` has a square window of `size x size` coverage values (how much of each pixel is
//! the part's colour, 0 outside; row-major, y down) whose top-left pixel sits at `origins[i]` in
//! a common pixel frame. Its centre is the centroid of the coverage inside a disk of radius
//! `r + 2` px about the pixel nearest the current centre, keeping only the pixels on the part's
//! side of the perpendicular bisector to every neighbour closer than `2 r + 6` px; repeated
//! `iterations` times. Also returned: the coverage area and the mean coverage of the ring from
//! `r + 1.5` to `r + 3.5` px (near 0 round a part, near 1 inside anything larger).

use crate::error::{Error, Result};

/// Refined centres (common frame), coverage areas [px^2] and ring coverages, one per part.
pub struct Centroids {
    /// Refined centres in the common pixel frame.
    pub centres: Vec<[f64; 2]>,
    /// Coverage inside each part's (split) disk window [px^2].
    pub area: Vec<f64>,
    /// Mean coverage of the ring from `r + 1.5` to `r + 3.5` px.
    pub ring: Vec<f64>,
}

/// See the module documentation. `cover` holds `n * size * size` values.
pub fn coverage_centroids(
    cover: &[f32],
    size: usize,
    origins: &[[f64; 2]],
    centres: &[[f64; 2]],
    radius: f64,
    iterations: usize,
) -> Result<Centroids> {
    let n = centres.len();
    if origins.len() != n || cover.len() != n * size * size {
        return Err(Error::parameter(
            "cover",
            format!(
                "must hold {n} windows of {size} x {size} values and {n} origins; got {} values, {} origins",
                cover.len(),
                origins.len()
            ),
        ));
    }
    if !(radius.is_finite() && radius > 0.0) {
        return Err(Error::parameter(
            "radius",
            format!("must be > 0; got {radius}"),
        ));
    }
    let reach = (radius + 3.5).ceil() as i64;
    if size as i64 <= 2 * reach {
        return Err(Error::parameter(
            "size",
            format!(
                "windows of {size} px cannot hold a part of radius {radius} px (need > {})",
                2 * reach
            ),
        ));
    }
    let (lo, hi) = (reach, size as i64 - 1 - reach);
    let disk2 = (radius + 2.0).powi(2);
    let (ring_in2, ring_out2) = ((radius + 1.5).powi(2), (radius + 3.5).powi(2));
    let ring_offsets: Vec<(i64, i64)> = (-reach..=reach)
        .flat_map(|dy| (-reach..=reach).map(move |dx| (dy, dx)))
        .filter(|&(dy, dx)| {
            let d2 = (dx * dx + dy * dy) as f64;
            d2 > ring_in2 && d2 <= ring_out2
        })
        .collect();
    let ring_count = ring_offsets.len().max(1) as f64;
    // neighbours: fixed from the starting centres
    let near2 = (2.0 * radius + 6.0).powi(2);
    let neighbours: Vec<Vec<usize>> = (0..n)
        .map(|i| {
            (0..n)
                .filter(|&j| {
                    j != i && {
                        let (dx, dy) =
                            (centres[j][0] - centres[i][0], centres[j][1] - centres[i][1]);
                        dx * dx + dy * dy < near2
                    }
                })
                .collect()
        })
        .collect();
    let mut world: Vec<[f64; 2]> = centres.to_vec();
    let mut area = vec![0.0; n];
    let mut ring = vec![0.0; n];
    for step in 0..iterations {
        let current = world.clone(); // every part sees its neighbours where they were
        for i in 0..n {
            let local = [current[i][0] - origins[i][0], current[i][1] - origins[i][1]];
            let cx = (local[0].round() as i64).clamp(lo, hi);
            let cy = (local[1].round() as i64).clamp(lo, hi);
            let window = &cover[i * size * size..(i + 1) * size * size];
            let cuts: Vec<[f64; 3]> = neighbours[i]
                .iter()
                .map(|&j| {
                    // keep (p - c_i) . v < |v|^2 / 2, v = c_j - c_i, p relative to pixel (cx, cy)
                    let v = [current[j][0] - current[i][0], current[j][1] - current[i][1]];
                    let base = [cx as f64 - local[0], cy as f64 - local[1]];
                    [
                        v[0],
                        v[1],
                        0.5 * (v[0] * v[0] + v[1] * v[1]) - (base[0] * v[0] + base[1] * v[1]),
                    ]
                })
                .collect();
            let (mut m0, mut mx, mut my) = (0.0f64, 0.0f64, 0.0f64);
            let rd = (radius + 2.0).floor() as i64;
            for dy in -rd..=rd {
                // the disk's extent on this row, then one tight pass over a slice
                let span = (disk2 - (dy * dy) as f64).max(0.0).sqrt().floor() as i64;
                let row = ((cy + dy) as usize) * size;
                let start = row + (cx - span) as usize;
                let pixels = &window[start..start + (2 * span + 1) as usize];
                let fy = dy as f64;
                let (mut s0, mut sx) = (0.0f64, 0.0f64);
                if cuts.is_empty() {
                    for (k, &w) in pixels.iter().enumerate() {
                        let w = w as f64;
                        s0 += w;
                        sx += w * (k as i64 - span) as f64;
                    }
                } else {
                    for (k, &w) in pixels.iter().enumerate() {
                        let fx = (k as i64 - span) as f64;
                        if w == 0.0 || cuts.iter().any(|c| fx * c[0] + fy * c[1] >= c[2]) {
                            continue;
                        }
                        s0 += w as f64;
                        sx += w as f64 * fx;
                    }
                }
                m0 += s0;
                mx += sx;
                my += s0 * fy;
            }
            if step + 1 == iterations {
                let around: f64 = ring_offsets
                    .iter()
                    .map(|&(dy, dx)| {
                        window[((cy + dy) as usize) * size + (cx + dx) as usize] as f64
                    })
                    .sum();
                ring[i] = around / ring_count;
            }
            area[i] = m0;
            if m0 > 1e-3 {
                let half = radius / 2.0;
                world[i] = [
                    origins[i][0] + cx as f64 + (mx / m0).clamp(-half, half),
                    origins[i][1] + cy as f64 + (my / m0).clamp(-half, half),
                ];
            }
        }
    }
    Ok(Centroids {
        centres: world,
        area,
        ring,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A window with an anti-aliased disk (4 x 4 subsamples) at `centre`.
    fn disk_window(size: usize, centre: [f64; 2], r: f64) -> Vec<f32> {
        let mut w = vec![0.0f32; size * size];
        for y in 0..size {
            for x in 0..size {
                let mut hits = 0;
                for sy in 0..4 {
                    for sx in 0..4 {
                        let px = x as f64 - 0.375 + 0.25 * sx as f64 - centre[0];
                        let py = y as f64 - 0.375 + 0.25 * sy as f64 - centre[1];
                        if px * px + py * py <= r * r {
                            hits += 1;
                        }
                    }
                }
                w[y * size + x] = hits as f32 / 16.0;
            }
        }
        w
    }

    #[test]
    fn finds_a_disk_centre_from_a_few_pixels_away() {
        let (size, r) = (41, 8.0);
        let truth = [20.3, 19.6];
        let cover = disk_window(size, truth, r);
        let out =
            coverage_centroids(&cover, size, &[[100.0, 50.0]], &[[123.0, 67.5]], r, 3).unwrap();
        let c = out.centres[0];
        assert!(
            (c[0] - 120.3).abs() < 0.02 && (c[1] - 69.6).abs() < 0.02,
            "{c:?}"
        );
        assert!((out.area[0] - std::f64::consts::PI * r * r).abs() < 2.0);
        assert!(out.ring[0] < 1e-9);
    }

    #[test]
    fn touching_disks_are_split_at_their_bisector() {
        let (size, r) = (61, 8.0);
        let (a, b) = ([25.0, 30.2], [41.1, 30.2]); // 16.1 px apart: touching
        let mut cover = disk_window(size, a, r);
        for (x, y) in cover.iter_mut().zip(disk_window(size, b, r)) {
            *x += y;
        }
        let two = [cover.clone(), cover].concat();
        let out = coverage_centroids(
            &two,
            size,
            &[[0.0, 0.0]; 2],
            &[[26.0, 31.0], [40.0, 29.0]],
            r,
            3,
        )
        .unwrap();
        // pixels straddling the tangent point hold both disks: about 0.05 px of bias each
        assert!((out.centres[0][0] - a[0]).abs() < 0.1 && (out.centres[1][0] - b[0]).abs() < 0.1);
        assert!((out.centres[0][1] - a[1]).abs() < 0.02 && (out.centres[1][1] - b[1]).abs() < 0.02);
    }

    #[test]
    fn inside_a_large_blob_the_ring_is_full() {
        let size = 41;
        let out = coverage_centroids(
            &vec![1.0; size * size],
            size,
            &[[0.0, 0.0]],
            &[[20.0, 20.0]],
            8.0,
            2,
        )
        .unwrap();
        assert!((out.ring[0] - 1.0).abs() < 1e-12);
    }

    #[test]
    fn bad_shapes_are_errors() {
        assert!(coverage_centroids(&[0.0; 10], 41, &[[0.0, 0.0]], &[[0.0, 0.0]], 8.0, 1).is_err());
        assert!(coverage_centroids(&[0.0; 25], 5, &[[0.0, 0.0]], &[[2.0, 2.0]], 8.0, 1).is_err());
        assert!(
            coverage_centroids(&[0.0; 1681], 41, &[[0.0, 0.0]], &[[2.0, 2.0]], -1.0, 1).is_err()
        );
    }
}
