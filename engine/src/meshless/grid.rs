//! The background grid of integration cells (seed 004 §3.2.2): a regular grid of rectangles
//! (2D) or boxes (3D) over the body, each integrated with one Gauss point at its centre,
//! weighted by the cell's area or volume. The grid need not conform to the boundary; cells
//! whose centre lies outside the body are dropped by the caller's `inside` test.

/// One integration point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IntegrationPoint {
    /// Position (m; z = 0 in 2D).
    pub x: [f64; 3],
    /// Weight: the cell's area (2D, per metre of thickness) or volume (3D).
    pub weight: f64,
}

/// The centres of a `cells[0] × cells[1] (× cells[2])` grid over the box `[lo, hi]` in `dim`
/// dimensions whose centre satisfies `inside`.
pub fn box_grid(dim: usize, lo: [f64; 3], hi: [f64; 3], cells: [usize; 3], inside: impl Fn([f64; 3]) -> bool) -> Vec<IntegrationPoint> {
    let n = [cells[0].max(1), cells[1].max(1), if dim == 3 { cells[2].max(1) } else { 1 }];
    let h: Vec<f64> = (0..3).map(|k| if k < dim { (hi[k] - lo[k]) / n[k] as f64 } else { 1.0 }).collect();
    let weight: f64 = h[..dim].iter().product();
    let mut out = Vec::with_capacity(n[0] * n[1] * n[2]);
    for k in 0..n[2] {
        for j in 0..n[1] {
            for i in 0..n[0] {
                let idx = [i, j, k];
                let mut x = [0.0; 3];
                for d in 0..dim {
                    x[d] = lo[d] + (idx[d] as f64 + 0.5) * h[d];
                }
                if inside(x) {
                    out.push(IntegrationPoint { x, weight });
                }
            }
        }
    }
    out
}

/// A grid of `cells` over the box `[lo, hi]` with `q` points per axis in each cell (the
/// `q × q (× q)` centres of its sub-cells), and `2q` in the cells for which `refine(centre)`
/// holds — denser integration where the nodes are denser, e.g. around a cut.
pub fn refined_grid(
    dim: usize,
    lo: [f64; 3],
    hi: [f64; 3],
    cells: [usize; 3],
    q: usize,
    refine: impl Fn([f64; 3]) -> bool,
) -> Vec<IntegrationPoint> {
    let q = q.max(1);
    let coarse = box_grid(dim, lo, hi, cells, |_| true);
    let h: Vec<f64> = (0..3)
        .map(|k| if k < dim { (hi[k] - lo[k]) / cells[k].max(1) as f64 } else { 0.0 })
        .collect();
    let mut out = Vec::new();
    for c in coarse {
        let per = if refine(c.x) { 2 * q } else { q };
        let mut clo = c.x;
        let mut chi = c.x;
        for k in 0..dim {
            clo[k] -= 0.5 * h[k];
            chi[k] += 0.5 * h[k];
        }
        out.extend(box_grid(dim, clo, chi, [per; 3], |_| true));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_grid_integrates_the_body_measure() {
        let g = box_grid(2, [0.0; 3], [0.1, 0.1, 0.0], [10, 10, 1], |_| true);
        assert_eq!(g.len(), 100);
        assert!((g.iter().map(|p| p.weight).sum::<f64>() - 0.01).abs() < 1e-15);
        let b = box_grid(3, [0.0; 3], [0.1, 0.2, 0.3], [2, 3, 4], |_| true);
        assert!((b.iter().map(|p| p.weight).sum::<f64>() - 0.006).abs() < 1e-15);
        // a disc: cells whose centre is inside
        let d = box_grid(2, [-1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [200, 200, 1], |x| {
            x[0] * x[0] + x[1] * x[1] <= 1.0
        });
        let area: f64 = d.iter().map(|p| p.weight).sum();
        assert!((area - std::f64::consts::PI).abs() < 5e-3, "{area}");
    }

    #[test]
    fn a_refined_grid_integrates_the_same_measure_with_more_points() {
        let g = refined_grid(2, [0.0; 3], [1.0, 1.0, 0.0], [4, 4, 1], 2, |x| x[0] < 0.5);
        assert_eq!(g.len(), 8 * 4 + 8 * 16);
        assert!((g.iter().map(|p| p.weight).sum::<f64>() - 1.0).abs() < 1e-14);
        // exact for a bilinear integrand
        let i: f64 = g.iter().map(|p| p.weight * p.x[0] * p.x[1]).sum();
        assert!((i - 0.25).abs() < 1e-14);
    }
}
