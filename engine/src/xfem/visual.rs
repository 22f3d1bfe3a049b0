//! Visual meshes mapped to the simulation mesh (seed 003 §3.2, §3.4): a finer surface whose
//! vertices are embedded in the tetrahedra by barycentric coordinates and follow the
//! deformation — on each side of a cut, the side's own.
//!
//! # The mapping
//! Each vertex `v` lies in a cell `e` (or, outside the simulation mesh, nearest to one: its
//! barycentric coordinates then extrapolate, exactly for any affine motion). Its displacement
//! is the XFEM field at its reference position,
//!
//! `u(v) = Σ_a N_a(v) (u_a + Σ_k H̃_k(v) q_k)`,
//!
//! which is the seed's "alternative mesh": in a cut cell, the virtual element of the side
//! `v` lies on (the sign of each enriched node's plane at `v`; a vertex exactly on a plane
//! counts as on its negative side, as a node does) carries it; its side is read from its own
//! position each time, never stored.
//!
//! # Re-association after a cut
//! A visual surface is rarely inside its tetrahedra (SOFA's smooth liver: 122 of 2,194
//! vertices are): most vertices hang just outside the cell nearest to them. A cut can pass
//! between such a vertex and its cell — the vertex on one side of the cut's plane, the whole
//! cell on the other — and a cell that is not cut carries one side only (its nodes' that are not
//! enriched). So once cut, each vertex whose cell is not a cut one is checked against the nearest cut cell (within
//! twice its distance to its own cell's centre): if that cell's plane separates the vertex from
//! its cell, the vertex moves to the cut cell (which carries both sides) as the seed
//! re-associates "the visual points connected with the discontinuous elements"
//! ([`Embedding::follow_cut`]).
//!
//! # Split surfaces
//! A surface split along the cut ([`super::visual_split`]) has vertices on the cut plane that
//! belong to one side (the two copies of an opened vertex) or to both (where it closes): their
//! side is given ([`Embedding::with_sides`]), not read from their position. A vertex of a given
//! side whose cell is not cut moves to the nearest cut cell, which carries both sides; one
//! following both sides takes their mean.

use std::path::Path;

use crate::mesh::{CellKind, Mesh};

use super::enrichment::Enrichment;

/// Which side of the cut a vertex of a split surface follows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum VertexSide {
    /// The side of the cut plane its position lies on (a vertex off the plane; a vertex on it
    /// counts as on the negative side, as a node does).
    #[default]
    Own,
    /// The positive side (an opened vertex's first copy).
    Positive,
    /// The negative side (an opened vertex's second copy).
    Negative,
    /// The mean of both sides: a vertex where the split surface closes.
    Mean,
}

/// A visual (or collision) surface: vertices (m) and triangles.
#[derive(Debug, Clone, PartialEq)]
pub struct VisualMesh {
    /// Vertex positions.
    pub vertices: Vec<[f64; 3]>,
    /// Triangles, counter-clockwise seen from outside.
    pub triangles: Vec<[usize; 3]>,
}

/// A visual mesh could not be read or embedded.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum VisualError {
    /// The file could not be read or parsed.
    #[error("{path}: {message}")]
    File {
        /// The file.
        path: String,
        /// What went wrong.
        message: String,
    },
    /// The simulation mesh is not made of tetrahedra.
    #[error("visual meshes are embedded in tetrahedra; this mesh has {0:?} cells")]
    NotTetrahedra(CellKind),
    /// The surface has no triangle, or refers to missing vertices, or holds non-finite values.
    #[error("the visual mesh is empty or malformed: {0}")]
    Malformed(String),
}

/// How the surface's edges are shared: what a closed, consistently oriented 2-manifold has
/// none of.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct EdgeReport {
    /// Edges of one triangle only (holes).
    pub boundary: usize,
    /// Edges of three or more triangles.
    pub non_manifold: usize,
    /// Edges two triangles traverse in the same direction (inconsistent orientation).
    pub misoriented: usize,
}

impl EdgeReport {
    /// Whether the surface is a closed, consistently oriented 2-manifold (as far as edges tell).
    pub fn is_closed_manifold(&self) -> bool {
        *self == Self::default()
    }
}

impl VisualMesh {
    /// Reads a Wavefront OBJ file (polygons triangulated as fans, every object merged), its
    /// coordinates multiplied by `scale` (e.g. 0.01 for centimetres).
    pub fn load_obj(path: &Path, scale: f64) -> Result<Self, VisualError> {
        let file = |message: String| VisualError::File {
            path: path.display().to_string(),
            message,
        };
        let options = tobj::LoadOptions {
            triangulate: true,
            ..Default::default()
        };
        // read here, bounded and from a regular file only; material libraries are not opened
        // (a `mtllib` line may name any file: the visual surface needs none)
        let bytes = crate::files::read_regular(path, crate::files::MAX_VISUAL_BYTES).map_err(|e| file(e.to_string()))?;
        let positions = positions_only(&bytes).map_err(file)?;
        let (models, _materials) = tobj::load_obj_buf(&mut std::io::Cursor::new(positions), &options, |_| {
            Err(tobj::LoadError::OpenFileFailed)
        })
        .map_err(|e| file(e.to_string()))?;
        let mut out = VisualMesh {
            vertices: Vec::new(),
            triangles: Vec::new(),
        };
        for m in &models {
            let base = out.vertices.len();
            out.vertices.extend(
                m.mesh
                    .positions
                    .chunks_exact(3)
                    .map(|p| [f64::from(p[0]) * scale, f64::from(p[1]) * scale, f64::from(p[2]) * scale]),
            );
            out.triangles.extend(
                m.mesh
                    .indices
                    .chunks_exact(3)
                    .map(|t| [base + t[0] as usize, base + t[1] as usize, base + t[2] as usize]),
            );
        }
        out.check().map_err(|e| file(e.to_string()))?;
        Ok(out)
    }

    /// Checks the surface is not empty, refers to its own vertices and is finite.
    pub fn check(&self) -> Result<(), VisualError> {
        if self.triangles.is_empty() {
            return Err(VisualError::Malformed("no triangle".into()));
        }
        if let Some(t) = self.triangles.iter().find(|t| t.iter().any(|&v| v >= self.vertices.len())) {
            return Err(VisualError::Malformed(format!(
                "triangle {t:?} refers to a vertex beyond the {} given",
                self.vertices.len()
            )));
        }
        if self.vertices.iter().flatten().any(|x| !x.is_finite()) {
            return Err(VisualError::Malformed("a vertex is not finite".into()));
        }
        Ok(())
    }

    /// How the edges are shared ([`EdgeReport`]).
    pub fn edges(&self) -> EdgeReport {
        use std::collections::HashMap;
        // per undirected edge: (times used, times used from its lower vertex to its higher)
        let mut count: HashMap<(usize, usize), (u32, u32)> = HashMap::with_capacity(3 * self.triangles.len() / 2);
        for t in &self.triangles {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                let e = count.entry((a.min(b), a.max(b))).or_default();
                e.0 += 1;
                e.1 += u32::from(a < b);
            }
        }
        let mut r = EdgeReport::default();
        for &(n, forward) in count.values() {
            match n {
                1 => r.boundary += 1,
                2 if forward != 1 => r.misoriented += 1,
                2 => {}
                _ => r.non_manifold += 1,
            }
        }
        r
    }
}

/// The positions and faces of an OBJ file, for tobj to triangulate: its `v` lines, and its `f`
/// lines with each corner cut to its position index, checked to name a vertex given before it
/// (1-based, or negative: counted back from the last). Everything else — texture coordinates,
/// normals, groups, materials — is not drawn and is dropped: tobj's index arithmetic on those
/// overflows on indices such as `-9223372809` (found by the fuzzer), so it never sees them.
fn positions_only(bytes: &[u8]) -> Result<Vec<u8>, String> {
    let text = String::from_utf8_lossy(bytes);
    let mut out = String::with_capacity(text.len());
    let mut vertices: i64 = 0;
    for (line, l) in text.lines().enumerate() {
        let mut words = l.split_whitespace();
        match words.next() {
            Some("v") => {
                vertices += 1;
                out.push_str(l);
                out.push('\n');
            }
            Some("f") => {
                out.push('f');
                for corner in words {
                    let index = corner.split('/').next().unwrap_or("");
                    let i: i64 = index.parse().map_err(|_| {
                        let shown: String = corner.chars().take(32).collect();
                        format!("line {}: face corner '{shown}' has no vertex index", line + 1)
                    })?;
                    if i == 0 || i > vertices || i < -vertices {
                        return Err(format!(
                            "line {}: face vertex {i} is not one of the {vertices} vertices given before it",
                            line + 1
                        ));
                    }
                    out.push(' ');
                    out.push_str(&(if i > 0 { i } else { vertices + 1 + i }).to_string());
                }
                out.push('\n');
            }
            _ => {}
        }
    }
    Ok(out.into_bytes())
}

/// The vertices of a visual mesh embedded in a tetrahedral mesh.
#[derive(Debug, Clone, PartialEq)]
pub struct Embedding {
    /// The cell holding each vertex (the nearest for a vertex outside the mesh).
    pub cell: Vec<usize>,
    /// Its barycentric coordinates there (negative ones outside the cell).
    pub bary: Vec<[f64; 4]>,
    /// How far outside its cell each vertex lies, as the most negative barycentric coordinate
    /// (0 inside).
    pub outside: Vec<f64>,
    /// The side of a cut each vertex follows ([`VertexSide::Own`] unless given).
    pub side: Vec<VertexSide>,
    /// How many (vertex, cell) pairs the embedding tried: its cost, a small multiple of the
    /// number of vertices.
    pub examined: usize,
}

/// Barycentric coordinates of `p` in the tetrahedron `x`.
fn barycentric(x: &[[f64; 3]; 4], p: [f64; 3]) -> [f64; 4] {
    let m = nalgebra::Matrix3::from_fn(|i, j| x[j + 1][i] - x[0][i]);
    let r = nalgebra::Vector3::new(p[0] - x[0][0], p[1] - x[0][1], p[2] - x[0][2]);
    match m.try_inverse() {
        Some(inv) => {
            let l = inv * r;
            [1.0 - l[0] - l[1] - l[2], l[0], l[1], l[2]]
        }
        None => [f64::NEG_INFINITY; 4],
    }
}

impl Embedding {
    /// Embeds `vertices` in the tetrahedra of `mesh`: each in the cell that holds it (found
    /// through a grid of the cells' bounding boxes), or the cell it is least outside of among
    /// those near it: the cells of the grid's slots in Chebyshev shells round the vertex's slot
    /// (the nearest slot for a vertex outside the grid), up to one shell past the first that
    /// holds any cell. The cost is linear in the number of vertices (a search of every cell per
    /// vertex outside the mesh made a surface of 3,000 small closed boxes cost up to 2 s a frame;
    /// [`Embedding::examined`] counts what was tried).
    pub fn new(mesh: &Mesh, vertices: &[[f64; 3]]) -> Result<Self, VisualError> {
        if mesh.kind != CellKind::Tet4 {
            return Err(VisualError::NotTetrahedra(mesh.kind));
        }
        let nc = mesh.n_cells();
        if nc == 0 {
            return Err(VisualError::Malformed("the simulation mesh has no cell".into()));
        }
        let (lo, hi) = mesh.bounding_box();
        let cells_per_axis = ((nc as f64).cbrt().ceil() as usize).clamp(1, 64);
        let size: [f64; 3] = std::array::from_fn(|k| ((hi[k] - lo[k]) / cells_per_axis as f64).max(f64::MIN_POSITIVE));
        let slot = |p: [f64; 3], k: usize| (((p[k] - lo[k]) / size[k]).floor().max(0.0) as usize).min(cells_per_axis - 1);
        let mut grid: Vec<Vec<usize>> = vec![Vec::new(); cells_per_axis.pow(3)];
        let mut x = [[0.0; 3]; 4];
        let mut coords = Vec::with_capacity(nc);
        for c in 0..nc {
            mesh.cell_coords(c, &mut x);
            coords.push(x);
            let (mut a, mut b) = (x[0], x[0]);
            for p in &x[1..] {
                for k in 0..3 {
                    a[k] = a[k].min(p[k]);
                    b[k] = b[k].max(p[k]);
                }
            }
            for i in slot(a, 0)..=slot(b, 0) {
                for j in slot(a, 1)..=slot(b, 1) {
                    for k in slot(a, 2)..=slot(b, 2) {
                        grid[(i * cells_per_axis + j) * cells_per_axis + k].push(c);
                    }
                }
            }
        }
        let n = cells_per_axis as isize;
        // the last vertex each cell was tried for: a cell in several slots is tried once
        let mut tried = vec![usize::MAX; nc];
        let mut examined = 0usize;
        let mut e = Embedding {
            cell: Vec::with_capacity(vertices.len()),
            bary: Vec::with_capacity(vertices.len()),
            outside: Vec::with_capacity(vertices.len()),
            side: vec![VertexSide::Own; vertices.len()],
            examined: 0,
        };
        for (v, &p) in vertices.iter().enumerate() {
            let home = [0, 1, 2].map(|k| slot(p, k) as isize);
            let mut best: Option<(usize, [f64; 4], f64)> = None;
            let mut try_shell = |r: isize, best: &mut Option<(usize, [f64; 4], f64)>| {
                let mut any = false;
                for i in (home[0] - r).max(0)..=(home[0] + r).min(n - 1) {
                    for j in (home[1] - r).max(0)..=(home[1] + r).min(n - 1) {
                        for k in (home[2] - r).max(0)..=(home[2] + r).min(n - 1) {
                            let on_shell = (i - home[0]).abs() == r || (j - home[1]).abs() == r || (k - home[2]).abs() == r;
                            if !on_shell {
                                continue;
                            }
                            for &c in &grid[((i * n + j) * n + k) as usize] {
                                any = true;
                                if tried[c] == v {
                                    continue;
                                }
                                tried[c] = v;
                                examined += 1;
                                let l = barycentric(&coords[c], p);
                                let worst = l.iter().copied().fold(f64::INFINITY, f64::min);
                                if best.as_ref().is_none_or(|b| worst > b.2) {
                                    *best = Some((c, l, worst));
                                }
                            }
                        }
                    }
                }
                any
            };
            // the vertex's own slot; then, unless a cell there holds it, the shells round it up
            // to one past the first that holds a cell
            let mut first = try_shell(0, &mut best).then_some(0);
            if best.as_ref().is_none_or(|b| b.2 < -1e-12) {
                let mut r = 1;
                while r < n && first.is_none_or(|f| r <= f + 1) {
                    if try_shell(r, &mut best) && first.is_none() {
                        first = Some(r);
                    }
                    r += 1;
                }
            }
            let (c, l, worst) = best.ok_or_else(|| VisualError::Malformed("the simulation mesh has no cell".into()))?;
            if !worst.is_finite() {
                return Err(VisualError::Malformed(format!(
                    "vertex {p:?} lies in no cell (degenerate tetrahedra)"
                )));
            }
            e.cell.push(c);
            e.bary.push(l);
            e.outside.push((-worst).max(0.0));
        }
        e.examined = examined;
        Ok(e)
    }

    /// The same embedding, each vertex following the side given (a split surface's,
    /// [`super::visual_split::SplitSurface::side`]); the sides are those of the vertices, in
    /// order (missing ones follow their own).
    pub fn with_sides(mut self, side: &[VertexSide]) -> Self {
        for (s, &given) in self.side.iter_mut().zip(side) {
            *s = given;
        }
        self
    }

    /// Re-associates, after the cut `enr`, every vertex whose cell is not cut (it carries one
    /// side only) and that the cut separates from it (module docs); returns how many moved.
    pub fn follow_cut(&mut self, mesh: &Mesh, enr: &Enrichment, vertices: &[[f64; 3]]) -> usize {
        if enr.cut_cells.is_empty() {
            return 0;
        }
        let centroid = |c: usize| {
            let cell = mesh.cell(c);
            let mut m = [0.0; 3];
            for &a in cell {
                (0..3).for_each(|k| m[k] += mesh.nodes[a][k] / cell.len() as f64);
            }
            m
        };
        let dist2 = |a: [f64; 3], b: [f64; 3]| (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>();
        let cut: Vec<([f64; 3], usize, super::subcell::Plane)> = enr.cut_cells.iter().map(|&(c, p)| (centroid(c), c, p)).collect();
        let mut x = [[0.0; 3]; 4];
        let mut moved = 0;
        for (v, &p) in vertices.iter().enumerate() {
            let host = self.cell[v];
            if mesh.cell(host).iter().all(|&a| enr.index(a).is_some()) {
                continue; // a cut cell: it carries both sides
            }
            let given = matches!(self.side[v], VertexSide::Positive | VertexSide::Negative);
            let own = centroid(host);
            let reach = 4.0 * dist2(p, own);
            let Some((_, c, plane)) = cut
                .iter()
                .filter(|(m, _, _)| dist2(p, *m) <= reach)
                .min_by(|a, b| dist2(p, a.0).total_cmp(&dist2(p, b.0)))
            else {
                continue;
            };
            if given || (plane.phi(p) > 0.0) != (plane.phi(own) > 0.0) {
                mesh.cell_coords(*c, &mut x);
                let l = barycentric(&x, p);
                self.cell[v] = *c;
                self.bary[v] = l;
                self.outside[v] = (-l.iter().copied().fold(f64::INFINITY, f64::min)).max(0.0);
                moved += 1;
            }
        }
        moved
    }

    /// The displacement of every vertex (`out`, 3 per vertex) for the generalized
    /// displacements `d` (the nodes', then the enriched nodes' jumps) of `mesh` cut by `enr`
    /// (module docs); `vertices` are the embedded ones.
    pub fn displacements(&self, mesh: &Mesh, enr: &Enrichment, vertices: &[[f64; 3]], d: &[f64], out: &mut [f64]) {
        let n = mesh.n_nodes();
        for (v, (&c, l)) in self.cell.iter().zip(&self.bary).enumerate() {
            let mut u = [0.0; 3];
            for (a, &node) in mesh.cell(c).iter().enumerate() {
                let mut p = [d[3 * node], d[3 * node + 1], d[3 * node + 2]];
                if let Some(k) = enr.index(node) {
                    let s = match self.side[v] {
                        VertexSide::Own => enr.shifted(k, enr.planes[k].phi(vertices[v]) > 0.0),
                        VertexSide::Positive => enr.shifted(k, true),
                        VertexSide::Negative => enr.shifted(k, false),
                        VertexSide::Mean => 0.5 * (enr.shifted(k, true) + enr.shifted(k, false)),
                    };
                    for i in 0..3 {
                        p[i] += s * d[3 * (n + k) + i];
                    }
                }
                for i in 0..3 {
                    u[i] += l[a] * p[i];
                }
            }
            out[3 * v..3 * v + 3].copy_from_slice(&u);
        }
    }
}
