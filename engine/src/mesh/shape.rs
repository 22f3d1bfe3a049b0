//! Shape functions of the two cell kinds and their gradients.
//!
//! Tetrahedron (natural coordinates ξ, η, ζ ≥ 0, ξ+η+ζ ≤ 1):
//! `N = [1−ξ−η−ζ, ξ, η, ζ]`, constant gradients.
//! Hexahedron (ξ, η, ζ ∈ [−1, 1]): `N_a = ⅛(1+ξ ξ_a)(1+η η_a)(1+ζ ζ_a)` with the node
//! signs of [`HEX_NODES`].

/// Natural coordinates of the hexahedron's nodes, in VTK order.
pub const HEX_NODES: [[f64; 3]; 8] = [
    [-1.0, -1.0, -1.0],
    [1.0, -1.0, -1.0],
    [1.0, 1.0, -1.0],
    [-1.0, 1.0, -1.0],
    [-1.0, -1.0, 1.0],
    [1.0, -1.0, 1.0],
    [1.0, 1.0, 1.0],
    [-1.0, 1.0, 1.0],
];

/// The 2×2×2 Gauss points of the hexahedron (weights 1).
pub fn hex_gauss_2() -> [[f64; 3]; 8] {
    let g = 1.0 / 3f64.sqrt();
    let mut out = [[0.0; 3]; 8];
    for (o, n) in out.iter_mut().zip(HEX_NODES.iter()) {
        *o = [n[0] * g, n[1] * g, n[2] * g];
    }
    out
}

/// Hexahedron shape functions at natural point `p`.
#[inline]
pub fn hex_n(p: [f64; 3]) -> [f64; 8] {
    let mut n = [0.0; 8];
    for (a, s) in HEX_NODES.iter().enumerate() {
        n[a] = 0.125 * (1.0 + p[0] * s[0]) * (1.0 + p[1] * s[1]) * (1.0 + p[2] * s[2]);
    }
    n
}

/// Hexahedron shape-function derivatives with respect to natural coordinates at `p`.
#[inline]
pub fn hex_dn(p: [f64; 3]) -> [[f64; 3]; 8] {
    let mut d = [[0.0; 3]; 8];
    for (a, s) in HEX_NODES.iter().enumerate() {
        let (x, y, z) = (1.0 + p[0] * s[0], 1.0 + p[1] * s[1], 1.0 + p[2] * s[2]);
        d[a] = [0.125 * s[0] * y * z, 0.125 * s[1] * x * z, 0.125 * s[2] * x * y];
    }
    d
}

/// Tetrahedron shape-function derivatives with respect to natural coordinates (constant).
pub const TET_DN: [[f64; 3]; 4] = [[-1.0, -1.0, -1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

/// Jacobian `J_ij = Σ_a x_a,i ∂N_a/∂ξ_j`, its determinant, and the physical gradients
/// `∇N_a = J⁻ᵀ ∂N_a/∂ξ` written into `grad`. Returns `det J` (≤ 0 means an inverted point;
/// `grad` is then left unspecified).
#[inline]
pub fn physical_gradients(x: &[[f64; 3]], dn: &[[f64; 3]], grad: &mut [[f64; 3]]) -> f64 {
    let mut j = [[0.0; 3]; 3];
    for (xa, da) in x.iter().zip(dn) {
        for i in 0..3 {
            for k in 0..3 {
                j[i][k] += xa[i] * da[k];
            }
        }
    }
    let det = j[0][0] * (j[1][1] * j[2][2] - j[1][2] * j[2][1]) - j[0][1] * (j[1][0] * j[2][2] - j[1][2] * j[2][0])
        + j[0][2] * (j[1][0] * j[2][1] - j[1][1] * j[2][0]);
    if det <= 0.0 {
        return det;
    }
    let inv_det = 1.0 / det;
    // inverse of J (row-major): inv[k][i] with ∂ξ_k/∂x_i
    let inv = [
        [
            (j[1][1] * j[2][2] - j[1][2] * j[2][1]) * inv_det,
            (j[0][2] * j[2][1] - j[0][1] * j[2][2]) * inv_det,
            (j[0][1] * j[1][2] - j[0][2] * j[1][1]) * inv_det,
        ],
        [
            (j[1][2] * j[2][0] - j[1][0] * j[2][2]) * inv_det,
            (j[0][0] * j[2][2] - j[0][2] * j[2][0]) * inv_det,
            (j[0][2] * j[1][0] - j[0][0] * j[1][2]) * inv_det,
        ],
        [
            (j[1][0] * j[2][1] - j[1][1] * j[2][0]) * inv_det,
            (j[0][1] * j[2][0] - j[0][0] * j[2][1]) * inv_det,
            (j[0][0] * j[1][1] - j[0][1] * j[1][0]) * inv_det,
        ],
    ];
    for (g, da) in grad.iter_mut().zip(dn) {
        // ∂N/∂x_i = Σ_k ∂N/∂ξ_k ∂ξ_k/∂x_i
        for i in 0..3 {
            g[i] = da[0] * inv[0][i] + da[1] * inv[1][i] + da[2] * inv[2][i];
        }
    }
    det
}

/// Determinant of the Jacobian only (no gradients).
#[inline]
pub fn jacobian_det(x: &[[f64; 3]], dn: &[[f64; 3]]) -> f64 {
    let mut j = [[0.0; 3]; 3];
    for (xa, da) in x.iter().zip(dn) {
        for i in 0..3 {
            for k in 0..3 {
                j[i][k] += xa[i] * da[k];
            }
        }
    }
    j[0][0] * (j[1][1] * j[2][2] - j[1][2] * j[2][1]) - j[0][1] * (j[1][0] * j[2][2] - j[1][2] * j[2][0])
        + j[0][2] * (j[1][0] * j[2][1] - j[1][1] * j[2][0])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hex_shape_functions_partition_unity_and_interpolate_nodes() {
        for (a, p) in HEX_NODES.iter().enumerate() {
            let n = hex_n(*p);
            for (b, v) in n.iter().enumerate() {
                assert_eq!(*v, if a == b { 1.0 } else { 0.0 });
            }
        }
        let n = hex_n([0.3, -0.2, 0.7]);
        assert!((n.iter().sum::<f64>() - 1.0).abs() < 1e-15);
        let d = hex_dn([0.3, -0.2, 0.7]);
        for k in 0..3 {
            assert!(d.iter().map(|g| g[k]).sum::<f64>().abs() < 1e-15);
        }
    }

    #[test]
    fn gradients_of_a_linear_field_are_exact() {
        // Affine map of the reference hex; the gradient of u = c·x must come out as c.
        let x: Vec<[f64; 3]> = HEX_NODES
            .iter()
            .map(|s| [2.0 * s[0] + 0.3 * s[1], 1.5 * s[1], 0.7 * s[2] + 0.1 * s[0]])
            .collect();
        let c = [0.4, -1.1, 2.5];
        let u: Vec<f64> = x.iter().map(|p| c[0] * p[0] + c[1] * p[1] + c[2] * p[2]).collect();
        let mut g = [[0.0; 3]; 8];
        let det = physical_gradients(&x, &hex_dn([0.2, 0.1, -0.5]), &mut g);
        assert!(det > 0.0);
        for i in 0..3 {
            let gi: f64 = (0..8).map(|a| g[a][i] * u[a]).sum();
            assert!((gi - c[i]).abs() < 1e-13, "component {i}: {gi} vs {}", c[i]);
        }
    }
}
