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
}
