//! Cutting a node cloud (seed 004 §4.2.2, "Spatial discretisation of the cutting path"): the
//! nodes on the cut are split, nodes are inserted along it, and the cloud is then seen through
//! the cut.
//!
//! - A node lying on the cut is split into two nodes at the same position, one allocated to each
//!   face (the seed's `φ = ±ε`); both inherit its field variables and influence radius.
//! - The cut is discretised with stations about one nodal spacing apart; where no node lies on
//!   the cut within half a spacing of a station, two nodes (one per face) are added there, with
//!   the field variables interpolated by MLS and the mean radius of the nodes that cover it.
//! - In 2D, a single node is added at the tip if none is there (`φ = ψ = 0`): the cut is open at
//!   its tip, so this node is seen from both faces.
//!
//! Each face of the cut thereby carries its own row of nodes and can open; the new nodes sit at
//! the end of the numbering, so the indices of the prescribed nodes stay valid. Cutting again
//! with a longer cut (progressive cutting) splits the former tip node and discretises only the
//! new part: stations already carrying a pair are skipped.

use super::mls::{MlsError, NodeCloud, ShapeValues};
use crate::geometry::cut::Cut;

/// What cutting did to the cloud.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CutNodes {
    /// Existing nodes split in two.
    pub split: usize,
    /// Nodes added along the cut (two per station, one at a new tip).
    pub inserted: usize,
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// Cuts `cloud` (carrying the field variables `field`, `dim` per node) along `cut`, a cut that
/// contains any earlier one, with stations every `spacing` at most; only stations for which
/// `inside` holds receive nodes. Returns the new cloud, its field variables and a count.
pub fn cut_cloud(
    cloud: &NodeCloud,
    cut: Cut,
    field: &[f64],
    spacing: f64,
    inside: impl Fn([f64; 3]) -> bool,
) -> Result<(NodeCloud, Vec<f64>, CutNodes), MlsError> {
    let d = cloud.dim();
    assert_eq!(field.len(), d * cloud.len(), "field variables of the cloud");
    let mut points = cloud.points().to_vec();
    let mut radius = cloud.radii().to_vec();
    let mut side = cloud.sides().map_or_else(|| vec![1.0; points.len()], <[f64]>::to_vec);
    let mut values = field.to_vec();
    let mut count = CutNodes::default();
    let same = |a: [f64; 3], b: [f64; 3]| dist(a, b) <= 1e-12 * (1.0 + spacing);
    // split the nodes lying on the cut that have no twin yet
    let on: Vec<usize> = (0..points.len()).filter(|&i| cut.on_cut(points[i]).is_some()).collect();
    for &i in &on {
        let paired = on.iter().any(|&j| j != i && same(points[j], points[i]) && side[j] == -side[i]);
        if !paired {
            points.push(points[i]);
            radius.push(radius[i]);
            side.push(-side[i]);
            let v: Vec<f64> = values[d * i..d * (i + 1)].to_vec();
            values.extend(v);
            count.split += 1;
        }
    }
    let on_cut: Vec<[f64; 3]> = on.iter().map(|&i| points[i]).collect();
    // stations without a node: a pair (or one node at the tip)
    let tip = cut.tip();
    let mut s = ShapeValues::default();
    let mut added: Vec<[f64; 3]> = Vec::new();
    for p in cut.stations(spacing) {
        if !inside(p) {
            continue;
        }
        let is_tip = tip.is_some_and(|t| same(t, p));
        let occupied = if is_tip {
            points.iter().any(|q| same(*q, p))
        } else {
            on_cut.iter().chain(&added).any(|q| dist(*q, p) < 0.5 * spacing)
        };
        if occupied {
            continue;
        }
        let sides: &[f64] = if is_tip { &[1.0] } else { &[1.0, -1.0] };
        for &face in sides {
            cloud.shape_on_side(p, face, &mut s)?;
            let r = s.nodes.iter().map(|&j| cloud.radii()[j]).sum::<f64>() / s.nodes.len() as f64;
            points.push(p);
            radius.push(r);
            side.push(face);
            values.extend_from_slice(&s.interpolate(field, d)[..d]);
            count.inserted += 1;
        }
        added.push(p);
    }
    let out = NodeCloud::new(d, points, radius).with_cut(cut, side);
    Ok((out, values, count))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(n: usize) -> (NodeCloud, f64) {
        let h = 1.0 / (n - 1) as f64;
        let pts: Vec<[f64; 3]> = (0..n * n).map(|q| [(q % n) as f64 * h, (q / n) as f64 * h, 0.0]).collect();
        let r = vec![2.2 * h; pts.len()];
        (NodeCloud::new(2, pts, r), h)
    }

    #[test]
    fn nodes_on_the_cut_are_split_and_stations_filled() {
        let (cloud, h) = square(11);
        // a vertical cut along the grid line x = 0.5 from the top to y = 0.45 (between nodes)
        let cut = Cut::path(&[[0.5, 1.2], [0.5, 0.45]]).unwrap();
        let field: Vec<f64> = cloud.points().iter().flat_map(|p| [p[0], 2.0 * p[1]]).collect();
        let (cut_cloud, values, count) = cut_cloud(&cloud, cut, &field, h, |p| p[1] <= 1.0).unwrap();
        // nodes at y = 0.5, 0.6, ..., 1.0 on x = 0.5 are split; one node is added at the tip
        assert_eq!(count, CutNodes { split: 6, inserted: 1 });
        assert_eq!(cut_cloud.len(), 121 + 7);
        // the inserted tip node interpolates the (linear) field exactly
        let tip = cut_cloud.len() - 1;
        assert!((values[2 * tip] - 0.5).abs() < 1e-12 && (values[2 * tip + 1] - 0.9).abs() < 1e-12);
        // a point just left of the cut does not see the nodes just right of it, and vice versa
        let mut s = ShapeValues::default();
        cut_cloud.shape([0.49, 0.8, 0.0], &mut s).unwrap();
        assert!(s.nodes.iter().all(|&i| cut_cloud.points()[i][0] <= 0.5));
        assert!(s.nodes.iter().any(|&i| i >= 121), "the left twin of a split node");
        // below the tip both sides are seen
        cut_cloud.shape([0.49, 0.3, 0.0], &mut s).unwrap();
        assert!(s.nodes.iter().any(|&i| cut_cloud.points()[i][0] > 0.5));
        // the shape functions still reproduce linear fields on each face
        for x in [[0.48, 0.75, 0.0], [0.53, 0.75, 0.0], [0.5, 0.7, 0.0], [0.5, 0.45, 0.0]] {
            cut_cloud.shape(x, &mut s).unwrap();
            let sum: f64 = s.phi.iter().sum();
            let vx: f64 = s.nodes.iter().zip(&s.phi).map(|(&i, f)| f * cut_cloud.points()[i][0]).sum();
            assert!((sum - 1.0).abs() < 1e-12 && (vx - x[0]).abs() < 1e-12, "{x:?}");
        }
    }

    #[test]
    fn cutting_between_nodes_inserts_pairs_and_progresses() {
        let (cloud, h) = square(11);
        let field = vec![0.0; 2 * cloud.len()];
        let first = Cut::path(&[[0.27, 1.1], [0.27, 0.7]]).unwrap();
        let (c1, f1, n1) = cut_cloud(&cloud, first, &field, h, |p| p[1] <= 1.0).unwrap();
        // stations at y = 1.0 (inside), 0.9, 0.8 (pairs) and the tip 0.7
        assert_eq!(
            n1,
            CutNodes {
                split: 0,
                inserted: 2 * 3 + 1
            }
        );
        // progress down with a change of direction: the old tip is split, new stations filled
        let mut longer = c1.cut().unwrap().clone();
        longer.advance([0.35, 0.5]).unwrap();
        let (c2, _, n2) = cut_cloud(&c1, longer, &f1, h, |p| p[1] <= 1.0).unwrap();
        assert_eq!(n2.split, 1, "the former tip node");
        assert!(n2.inserted >= 3, "{n2:?}");
        assert_eq!(c2.len(), c1.len() + n2.split + n2.inserted);
    }
}
