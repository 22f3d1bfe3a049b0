//! Built-in meshes, so that defaults and tests need no files.
//!
//! - [`block_hex`]: a structured box of hexahedra.
//! - [`block_tet`]: the same box, each hexahedron split into six tetrahedra (the Kuhn
//!   split, which is conforming across neighbouring cubes).
//! - [`lobe`]: a smooth organ-like body: a flattened, slightly bent ellipsoid meshed with
//!   tetrahedra, obtained by mapping a structured cube onto the unit ball (shell by shell,
//!   `x' = x‖x‖_∞/‖x‖₂`) and then scaling and bending it.
//! - [`dome`]: a thin spherical cap of hexahedra (a cornea-like shell, seed 001 §6.1).

use super::{CellKind, Mesh};

/// Node index of grid point `(i, j, k)` in a grid with `n = [nx, ny, nz]` cells.
#[inline]
fn grid_index(n: [usize; 3], i: usize, j: usize, k: usize) -> usize {
    (k * (n[1] + 1) + j) * (n[0] + 1) + i
}

fn grid_nodes(origin: [f64; 3], size: [f64; 3], n: [usize; 3]) -> Vec<[f64; 3]> {
    let mut nodes = Vec::with_capacity((n[0] + 1) * (n[1] + 1) * (n[2] + 1));
    for k in 0..=n[2] {
        for j in 0..=n[1] {
            for i in 0..=n[0] {
                nodes.push([
                    origin[0] + size[0] * i as f64 / n[0] as f64,
                    origin[1] + size[1] * j as f64 / n[1] as f64,
                    origin[2] + size[2] * k as f64 / n[2] as f64,
                ]);
            }
        }
    }
    nodes
}

/// The eight corner nodes of grid cell `(i, j, k)`, VTK hexahedron order.
fn hex_corners(n: [usize; 3], i: usize, j: usize, k: usize) -> [usize; 8] {
    let g = |a, b, c| grid_index(n, a, b, c);
    [
        g(i, j, k),
        g(i + 1, j, k),
        g(i + 1, j + 1, k),
        g(i, j + 1, k),
        g(i, j, k + 1),
        g(i + 1, j, k + 1),
        g(i + 1, j + 1, k + 1),
        g(i, j + 1, k + 1),
    ]
}

/// A box `[origin, origin + size]` (m) divided into `n[0] × n[1] × n[2]` hexahedra.
///
/// # Panics
/// If a division count is zero or a size is not positive: a broken invariant of the caller
/// (the scene validates user values before calling).
pub fn block_hex(origin: [f64; 3], size: [f64; 3], n: [usize; 3]) -> Mesh {
    assert!(
        n.iter().all(|&d| d > 0) && size.iter().all(|&s| s > 0.0),
        "block needs positive sizes and divisions"
    );
    let nodes = grid_nodes(origin, size, n);
    let mut cells = Vec::with_capacity(8 * n[0] * n[1] * n[2]);
    for k in 0..n[2] {
        for j in 0..n[1] {
            for i in 0..n[0] {
                cells.extend_from_slice(&hex_corners(n, i, j, k));
            }
        }
    }
    Mesh::new(nodes, CellKind::Hex8, cells).expect("structured block is valid by construction")
}

/// VTK local index of the hexahedron corner with bit coordinates `(bx, by, bz)`.
const fn corner(bx: usize, by: usize, bz: usize) -> usize {
    let base = match (bx, by) {
        (0, 0) => 0,
        (1, 0) => 1,
        (1, 1) => 2,
        _ => 3,
    };
    base + 4 * bz
}

/// The Kuhn split of a cube into six tetrahedra sharing the diagonal from bit corner `f` to
/// its opposite: for each order `(a, b, c)` of the axes, the tetrahedron
/// `f, f⊕e_a, f⊕e_a⊕e_b, f⊕1`. With the same `f` in every cell the split is conforming; with
/// `f` mirrored across grid planes (as [`lobe`] does) it stays conforming, because a shared
/// face on a mirror plane gets the same diagonal from both sides.
fn kuhn(f: [usize; 3]) -> [[usize; 4]; 6] {
    let perms = [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]];
    let mut out = [[0; 4]; 6];
    for (t, p) in perms.iter().enumerate() {
        let mut b = f;
        let mut tet = [corner(b[0], b[1], b[2]), 0, 0, 0];
        for (k, &axis) in p.iter().enumerate() {
            b[axis] ^= 1;
            tet[k + 1] = corner(b[0], b[1], b[2]);
        }
        out[t] = tet;
    }
    out
}

/// A box like [`block_hex`], each hexahedron split into six tetrahedra.
pub fn block_tet(origin: [f64; 3], size: [f64; 3], n: [usize; 3]) -> Mesh {
    let hex = block_hex(origin, size, n);
    split_hexes(hex, |_| [0, 0, 0])
}

/// Splits every hexahedron into six tetrahedra (the Kuhn split with the diagonal corner chosen by
/// `diagonal_from(cell)`), fixing each tetrahedron's orientation.
pub fn split_hexes(hex: Mesh, diagonal_from: impl Fn(usize) -> [usize; 3]) -> Mesh {
    assert_eq!(hex.kind, CellKind::Hex8);
    let mut cells = Vec::with_capacity(hex.n_cells() * 24);
    let mut region = Vec::with_capacity(hex.n_cells() * 6);
    for (c, h) in hex.cells_iter().enumerate() {
        for t in kuhn(diagonal_from(c)) {
            let mut tet = [h[t[0]], h[t[1]], h[t[2]], h[t[3]]];
            let p = |i: usize| hex.nodes[tet[i]];
            let (a, b, cc, d) = (p(0), p(1), p(2), p(3));
            let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
            let v = [cc[0] - a[0], cc[1] - a[1], cc[2] - a[2]];
            let w = [d[0] - a[0], d[1] - a[1], d[2] - a[2]];
            let det = u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0]) + u[2] * (v[0] * w[1] - v[1] * w[0]);
            if det < 0.0 {
                tet.swap(1, 2);
            }
            cells.extend_from_slice(&tet);
            region.push(hex.cell_region[c]);
        }
    }
    let mut m = Mesh::new(hex.nodes, CellKind::Tet4, cells).expect("split of a valid hex mesh is valid");
    m.cell_region = region;
    m
}

/// Parameters of the built-in organ-like [`lobe`].
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LobeParams {
    /// Semi-axes of the ellipsoid along x, y, z (m).
    pub semi_axes: [f64; 3],
    /// Upward bend of the lobe: the height added at the tips `x = ±a`, as a fraction of the
    /// z semi-axis (0 = a plain ellipsoid).
    pub bend: f64,
    /// Cells of the structured cube mapped onto the body, along x, y, z.
    pub divisions: [usize; 3],
}

impl Default for LobeParams {
    /// A liver-lobe-sized body: 16 × 10 × 5 cm, bent by 60 % of its half-thickness, with
    /// 16 × 10 × 6 cube cells (1,309 nodes, 5,760 tetrahedra).
    fn default() -> Self {
        Self {
            semi_axes: [0.08, 0.05, 0.025],
            bend: 0.6,
            divisions: [16, 10, 6],
        }
    }
}

/// The cube-to-ball map `[−1, 1]³ → unit ball`: each cube shell `‖x‖_∞ = r` is projected
/// radially onto the sphere of radius r, `x' = x ‖x‖_∞ / ‖x‖₂`. Linear along every ray, so it
/// is one-to-one; unlike the smoother "elliptical grid" map it keeps a non-singular Jacobian at
/// the cube's corners, so the cells there stay well shaped.
fn cube_to_ball(p: [f64; 3]) -> [f64; 3] {
    let inf = p[0].abs().max(p[1].abs()).max(p[2].abs());
    let two = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
    if two == 0.0 {
        return p;
    }
    let f = inf / two;
    [p[0] * f, p[1] * f, p[2] * f]
}

/// A smooth organ-like body of tetrahedra centred at the origin (see the module docs).
pub fn lobe(p: &LobeParams) -> Mesh {
    let n = p.divisions;
    let mut hex = block_hex([-1.0, -1.0, -1.0], [2.0, 2.0, 2.0], n);
    let [a, b, c] = p.semi_axes;
    for q in &mut hex.nodes {
        let s = cube_to_ball(*q);
        let x = a * s[0];
        let y = b * s[1];
        let z = c * s[2] + p.bend * c * s[0] * s[0];
        *q = [x, y, z];
    }
    // Split every cube along the diagonal that starts at its corner nearest the centre, so
    // each tetrahedron has an interior node: cells along the cube's edges and corners, which
    // the map flattens, then give no boundary slivers.
    split_hexes(hex, |c| {
        let (i, j, k) = (c % n[0], (c / n[0]) % n[1], c / (n[0] * n[1]));
        let toward = |idx: usize, nn: usize| usize::from(2 * idx + 1 < nn);
        [toward(i, n[0]), toward(j, n[1]), toward(k, n[2])]
    })
}

/// A spherical cap shell: the sphere's radius of curvature (outer surface), the radius of its
/// circular base, the shell thickness (all m), and `[n, n, layers]` divisions.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DomeParams {
    /// Radius of curvature of the outer surface (m).
    pub curvature_radius: f64,
    /// Radius of the base circle of the outer surface (m).
    pub base_radius: f64,
    /// Shell thickness (m).
    pub thickness: f64,
    /// Cells across the base (both directions) and through the thickness.
    pub divisions: [usize; 3],
}

impl Default for DomeParams {
    /// A human cornea: 7.8 mm radius of curvature, 11.5 mm across, 0.55 mm thick.
    fn default() -> Self {
        Self {
            curvature_radius: 7.8e-3,
            base_radius: 5.75e-3,
            thickness: 0.55e-3,
            divisions: [12, 12, 2],
        }
    }
}

/// A cap of hexahedra with its axis along z, base circle at `z = 0` and apex at
/// `z = R − √(R² − a²)`. A structured square is mapped onto the base disc (ring by ring,
/// `x' = x‖x‖_∞/‖x‖₂`, as [`lobe`] does in 3D), each disc point is lifted radially from the
/// sphere's centre, and the layers run from the inner surface (radius `R − t`) to the outer
/// one. The base ring is the square's boundary. The outer surface is tagged as the physical
/// group `anterior` (tag 1) and the inner one as `posterior` (tag 2), so scenes can select
/// them (`{ group = "anterior" }`).
pub fn dome(p: &DomeParams) -> Mesh {
    let [n, _, layers] = p.divisions;
    let mut hex = block_hex([-1.0, -1.0, 0.0], [2.0, 2.0, 1.0], [n, n, layers]);
    let (r, a, t) = (p.curvature_radius, p.base_radius, p.thickness);
    let centre = -(r * r - a * a).sqrt();
    for q in &mut hex.nodes {
        let d = cube_to_ball([q[0], q[1], 0.0]);
        let (x, y) = (a * d[0], a * d[1]);
        let dir = [x / r, y / r, (r * r - x * x - y * y).max(0.0).sqrt() / r];
        let radius = r - t + t * q[2];
        *q = [radius * dir[0], radius * dir[1], centre + radius * dir[2]];
    }
    let dims = [n, n, layers];
    let surface = |k: usize, outward_up: bool| -> Vec<[usize; 4]> {
        let mut quads = Vec::with_capacity(n * n);
        for j in 0..n {
            for i in 0..n {
                let g = |a, b| grid_index(dims, a, b, k);
                quads.push(if outward_up {
                    [g(i, j), g(i + 1, j), g(i + 1, j + 1), g(i, j + 1)]
                } else {
                    [g(i, j), g(i, j + 1), g(i + 1, j + 1), g(i + 1, j)]
                });
            }
        }
        quads
    };
    for (tag, name, k, up) in [(1, "anterior", layers, true), (2, "posterior", 0, false)] {
        hex.tagged_faces.insert(
            tag,
            super::TaggedFaces {
                triangles: Vec::new(),
                quads: surface(k, up),
            },
        );
        hex.group_names.insert(tag, name.to_string());
    }
    hex
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::quality;

    #[test]
    fn the_dome_is_a_valid_shell_of_the_right_volume() {
        let p = DomeParams::default();
        let mut m = dome(&p);
        m.check_cells().expect("dome cells are positive");
        let v: f64 = quality::signed_volumes(&m).iter().sum();
        // the shell between the two spherical caps of the same cone of directions
        let (r, a, t) = (p.curvature_radius, p.base_radius, p.thickness);
        let cos = (r * r - a * a).sqrt() / r;
        let exact = 2.0 / 3.0 * std::f64::consts::PI * (1.0 - cos) * (r.powi(3) - (r - t).powi(3));
        assert!((v - exact).abs() / exact < 0.03, "volume {v} vs {exact}");
        let apex = m.nodes.iter().map(|q| q[2]).fold(f64::MIN, f64::max);
        assert!((apex - (r - (r * r - a * a).sqrt())).abs() < 1e-12);
        // the anterior group is the outer surface: every node at the outer radius
        let outer: Vec<usize> = m.tagged_faces[&1].quads.iter().flatten().copied().collect();
        let c = -(r * r - a * a).sqrt();
        assert!(outer.iter().all(|&i| {
            let q = m.nodes[i];
            ((q[0] * q[0] + q[1] * q[1] + (q[2] - c).powi(2)).sqrt() - r).abs() < 1e-12
        }));
    }

    #[test]
    fn blocks_have_expected_counts_and_volume() {
        let h = block_hex([0.0; 3], [2.0, 1.0, 0.5], [4, 2, 3]);
        assert_eq!((h.n_nodes(), h.n_cells()), (5 * 3 * 4, 24));
        let v: f64 = quality::signed_volumes(&h).iter().sum();
        assert!((v - 1.0).abs() < 1e-12);
        let t = block_tet([0.0; 3], [2.0, 1.0, 0.5], [4, 2, 3]);
        assert_eq!(t.n_cells(), 144);
        let vols = quality::signed_volumes(&t);
        assert!(vols.iter().all(|v| *v > 0.0));
        assert!((vols.iter().sum::<f64>() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn tet_block_is_conforming() {
        // In a conforming tetrahedral mesh every interior face is shared by exactly two
        // cells, so the boundary is just the box surface: 2 triangles per boundary quad.
        let t = block_tet([0.0; 3], [1.0; 3], [3, 3, 3]);
        let b = crate::mesh::boundary::Boundary::of(&t);
        assert_eq!(b.faces.len(), 6 * 9 * 2);
    }

    #[test]
    fn lobe_is_valid_and_close_to_the_ellipsoid_volume() {
        let p = LobeParams::default();
        let mut m = lobe(&p);
        m.check_cells().expect("lobe cells are positive");
        let v: f64 = quality::signed_volumes(&m).iter().sum();
        let exact = 4.0 / 3.0 * std::f64::consts::PI * p.semi_axes.iter().product::<f64>();
        // The bend is a shear in z (volume-preserving); the faceted surface loses a few %.
        assert!((v - exact).abs() / exact < 0.05, "volume {v} vs {exact}");
        let q = quality::summarize(&m);
        eprintln!("lobe quality min {:?} mean {:?}", q.tet_quality_min, q.tet_quality_mean);
        assert!(q.tet_quality_min.unwrap() > 0.05, "min quality {:?}", q.tet_quality_min);
    }
}
