//! A uniform grid over a closed surface: which triangles lie in each cell, and whether a cell
//! lies inside the body, outside it, or on its boundary.
//!
//! Each cell lists the triangles whose bounding box overlaps it (CSR). The grid has one empty
//! layer of cells around the surface's box, so its border is outside; the empty cells reached
//! from it by face-adjacent empty cells are outside, and the empty cells left over are
//! enclosed by the surface: inside. A closed surface cannot be crossed between two empty
//! cells, so the classification is exact for every empty cell; for a boundary cell the
//! caller decides with the nearest triangle.

/// Where a grid cell lies.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CellClass {
    /// Outside the body (or outside the grid).
    Outside,
    /// Holds part of the surface.
    Boundary,
    /// Enclosed by the surface.
    Inside,
}

/// Most cells per axis (besides the empty border layers).
const MAX_CELLS: usize = 64;

/// The grid (see the module docs).
#[derive(Debug, Clone)]
pub struct Grid {
    origin: [f64; 3],
    cell: f64,
    dims: [usize; 3],
    ptr: Vec<u32>,
    tris: Vec<u32>,
    class: Vec<CellClass>,
}

impl Grid {
    /// Bytes of its buffers.
    pub fn heap_bytes(&self) -> usize {
        use crate::memory::vec_bytes;
        vec_bytes(&self.ptr) + vec_bytes(&self.tris) + vec_bytes(&self.class)
    }

    /// Bins triangles given by their bounding boxes `(lo, hi)`.
    pub fn new(boxes: &[([f64; 3], [f64; 3])]) -> Self {
        let lo = [0, 1, 2].map(|k| boxes.iter().map(|b| b.0[k]).fold(f64::INFINITY, f64::min));
        let hi = [0, 1, 2].map(|k| boxes.iter().map(|b| b.1[k]).fold(f64::NEG_INFINITY, f64::max));
        if boxes.is_empty() || !lo.iter().chain(&hi).all(|x| x.is_finite()) {
            return Self {
                origin: [0.0; 3],
                cell: 1.0,
                dims: [0; 3],
                ptr: vec![0],
                tris: Vec::new(),
                class: Vec::new(),
            };
        }
        // cells about two mean triangle sizes wide, at most MAX_CELLS per axis
        let mean = boxes
            .iter()
            .map(|b| (0..3).map(|k| b.1[k] - b.0[k]).fold(0.0, f64::max))
            .sum::<f64>()
            / boxes.len() as f64;
        let extent = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max);
        let cell = (2.0 * mean).max(extent / MAX_CELLS as f64).max(f64::MIN_POSITIVE);
        // one empty layer on each side
        let origin = lo.map(|x| x - cell);
        let dims = [0, 1, 2].map(|k| (((hi[k] - lo[k]) / cell).floor() as usize + 1).min(MAX_CELLS) + 2);
        let index = |x: f64, k: usize| (((x - origin[k]) / cell).floor().max(1.0) as usize).min(dims[k] - 2);
        let mut lists: Vec<Vec<u32>> = vec![Vec::new(); dims[0] * dims[1] * dims[2]];
        for (t, (a, b)) in boxes.iter().enumerate() {
            for i in index(a[0], 0)..=index(b[0], 0) {
                for j in index(a[1], 1)..=index(b[1], 1) {
                    for l in index(a[2], 2)..=index(b[2], 2) {
                        lists[(i * dims[1] + j) * dims[2] + l].push(t as u32);
                    }
                }
            }
        }
        let mut ptr = vec![0u32];
        let mut tris = Vec::new();
        let mut class = Vec::with_capacity(lists.len());
        for l in lists {
            class.push(if l.is_empty() { CellClass::Inside } else { CellClass::Boundary });
            tris.extend(l);
            ptr.push(tris.len() as u32);
        }
        let mut grid = Self {
            origin,
            cell,
            dims,
            ptr,
            tris,
            class,
        };
        grid.flood_outside();
        grid
    }

    /// Marks the empty cells reachable from the border as outside (the rest stay inside).
    fn flood_outside(&mut self) {
        let [nx, ny, nz] = self.dims;
        let at = |i: usize, j: usize, l: usize| (i * ny + j) * nz + l;
        let mut stack = vec![(0usize, 0usize, 0usize)];
        self.class[0] = CellClass::Outside;
        while let Some((i, j, l)) = stack.pop() {
            let mut visit = |i: usize, j: usize, l: usize, class: &mut Vec<CellClass>| {
                let c = at(i, j, l);
                if class[c] == CellClass::Inside {
                    class[c] = CellClass::Outside;
                    stack.push((i, j, l));
                }
            };
            if i > 0 {
                visit(i - 1, j, l, &mut self.class);
            }
            if i + 1 < nx {
                visit(i + 1, j, l, &mut self.class);
            }
            if j > 0 {
                visit(i, j - 1, l, &mut self.class);
            }
            if j + 1 < ny {
                visit(i, j + 1, l, &mut self.class);
            }
            if l > 0 {
                visit(i, j, l - 1, &mut self.class);
            }
            if l + 1 < nz {
                visit(i, j, l + 1, &mut self.class);
            }
        }
    }

    /// The cell holding `p`, if it lies in the grid.
    fn cell_of(&self, p: [f64; 3]) -> Option<[usize; 3]> {
        if self.dims[0] == 0 {
            return None;
        }
        let mut c = [0usize; 3];
        for k in 0..3 {
            let x = ((p[k] - self.origin[k]) / self.cell).floor();
            if !(x >= 0.0 && x < self.dims[k] as f64) {
                return None;
            }
            c[k] = x as usize;
        }
        Some(c)
    }

    /// The class of the cell holding `p` ([`CellClass::Outside`] beyond the grid).
    pub fn class_of(&self, p: [f64; 3]) -> CellClass {
        match self.cell_of(p) {
            Some([i, j, l]) => self.class[(i * self.dims[1] + j) * self.dims[2] + l],
            None => CellClass::Outside,
        }
    }

    /// Calls `visit` with every triangle listed in a cell that overlaps the box `p ± reach`
    /// (a triangle may come more than once).
    pub fn for_each_near(&self, p: [f64; 3], reach: f64, mut visit: impl FnMut(usize)) {
        if self.dims[0] == 0 {
            return;
        }
        let mut range = [(0usize, 0usize); 3];
        for k in 0..3 {
            let a = ((p[k] - reach - self.origin[k]) / self.cell).floor();
            let b = ((p[k] + reach - self.origin[k]) / self.cell).floor();
            if !(b >= 0.0 && a <= (self.dims[k] - 1) as f64) {
                return;
            }
            range[k] = (a.max(0.0) as usize, (b as usize).min(self.dims[k] - 1));
        }
        for i in range[0].0..=range[0].1 {
            for j in range[1].0..=range[1].1 {
                for l in range[2].0..=range[2].1 {
                    self.visit_cell([i, j, l], &mut visit);
                }
            }
        }
    }

    fn visit_cell(&self, [i, j, l]: [usize; 3], visit: &mut impl FnMut(usize)) {
        let c = (i * self.dims[1] + j) * self.dims[2] + l;
        for &t in &self.tris[self.ptr[c] as usize..self.ptr[c + 1] as usize] {
            visit(t as usize);
        }
    }

    /// The triangle nearest to `p` (a point in the grid) by `dist2(t)`, visiting shells of
    /// cells around `p`'s cell until no farther shell can hold a nearer triangle; `None` for
    /// a point outside the grid or an empty grid. Cost grows with the distance to the
    /// surface (in cells), squared.
    pub fn nearest(&self, p: [f64; 3], mut dist2: impl FnMut(usize) -> f64) -> Option<(usize, f64)> {
        let c = self.cell_of(p)?;
        let mut best: Option<(usize, f64)> = None;
        let max_ring = self.dims.iter().copied().max().unwrap_or(0);
        for ring in 0..=max_ring {
            let lo = c.map(|x| x.saturating_sub(ring));
            let hi = [0, 1, 2].map(|k| (c[k] + ring).min(self.dims[k] - 1));
            for i in lo[0]..=hi[0] {
                for j in lo[1]..=hi[1] {
                    for l in lo[2]..=hi[2] {
                        let on_shell = [i, j, l].iter().zip(&c).any(|(&x, &cx)| x.abs_diff(cx) == ring);
                        if !on_shell {
                            continue;
                        }
                        self.visit_cell([i, j, l], &mut |t| {
                            let d = dist2(t);
                            if best.is_none_or(|b| d < b.1 || (d == b.1 && t < b.0)) {
                                best = Some((t, d));
                            }
                        });
                    }
                }
            }
            // every cell of the next shell is at least `ring` cells from p
            if let Some((_, d2)) = best {
                let reach = ring as f64 * self.cell;
                if d2 <= reach * reach {
                    break;
                }
            }
        }
        best
    }
}
