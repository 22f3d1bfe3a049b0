//! Scripted tool paths of headless runs: a [`Trajectory`] sampled at every tick as a probe's
//! (or, with a blade, a scalpel's) tool state, the built-in palpation of a scene's organ and
//! the built-in incisions along a cutting scene's pre-planned cuts.

use vademecum_bridge::trajectory::{BladeKey, KeyframeError, Trajectory};
use vademecum_engine::bundle::LoadedBundle;
use vademecum_engine::pipeline::{ToolInput, ToolKind};

/// Why a built-in path cannot be drawn on a scene.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BuiltinPathError {
    /// A pre-planned cut (numbered from 1) with fewer than two blade positions.
    #[error("cut {0} has fewer than two blade positions")]
    CutTooShort(usize),
    /// A pre-planned cut whose blade does not sweep a surface (a zero edge, or an edge along
    /// the cut's direction).
    #[error("cut {0}: its blade does not sweep a surface")]
    NoSweep(usize),
    /// An organ without a surface.
    #[error("the organ has no surface to cut")]
    NoSurface,
    /// A tearing scene whose load has no direction.
    #[error("the scene's load has no direction to pull along")]
    NoDirection,
    /// A bundle without a load node.
    #[error("the bundle has no load node to palpate")]
    NoLoadNode,
    /// An accessible surface without a triangle.
    #[error("the accessible surface has no triangle to palpate")]
    NoAccessibleTriangle,
    /// No accessible triangle around the middle of the accessible surface (no normal there).
    #[error("the middle of the accessible surface has no accessible triangle around it")]
    NoNormal,
    /// The keyframes drawn do not make a trajectory.
    #[error(transparent)]
    Keyframes(#[from] KeyframeError),
}

/// The tool state of `trajectory` at `t` seconds after its first keyframe: a probe's, or a
/// scalpel's if the trajectory has a blade.
pub fn tool_at(trajectory: &Trajectory, t: f64) -> ToolInput {
    let s = trajectory.at(t);
    let tool = ToolInput {
        kind: ToolKind::Probe,
        position_m: s.position_m,
        velocity_m_s: s.velocity_m_s,
        closure: s.closure,
        ..ToolInput::default()
    };
    match s.blade {
        None => tool,
        Some(b) => ToolInput {
            kind: ToolKind::Scalpel,
            blade_end_m: b.end_m,
            orientation: b.orientation,
            ..tool
        },
    }
}

/// The built-in incisions of a cutting scene: the scalpel follows each of `cuts` (the scene's
/// pre-planned blade positions, tip first then the other end of the edge) in turn — it comes
/// down along its edge from `lift_m` above the first position in 0.5 s, draws the cut through
/// every position in `seconds_per_cut`, and leaves the same way. "Above" is along the outward
/// normal of `b`'s surface nearest the edge's middle; the blade plane contains the edge and the
/// direction of the cut.
pub fn builtin_incisions(
    b: &LoadedBundle,
    cuts: &[&[[f64; 3]]],
    lift_m: f64,
    seconds_per_cut: f64,
) -> Result<Trajectory, BuiltinPathError> {
    use nalgebra::{UnitQuaternion, Vector3};
    let surface = vademecum_engine::contact::Surface::new(&b.nodes, b.surface.clone());
    let mut keys = Vec::new();
    let mut blades = Vec::new();
    let mut t = 0.0;
    for (c, points) in cuts.iter().enumerate() {
        let n = points.len() / 2;
        if n < 2 {
            return Err(BuiltinPathError::CutTooShort(c + 1));
        }
        let pos = |k: usize| (Vector3::from(points[2 * k + 1]), Vector3::from(points[2 * k]));
        let (tip0, end0) = pos(0);
        let (tip1, _) = pos(n - 1);
        let edge = end0 - tip0;
        let along = tip1 - tip0;
        let normal = edge.cross(&along);
        if edge.norm() == 0.0 || normal.norm() <= 1e-12 * edge.norm() * along.norm() {
            return Err(BuiltinPathError::NoSweep(c + 1));
        }
        let q = UnitQuaternion::rotation_between(&Vector3::y(), &normal.normalize())
            .unwrap_or_else(|| UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI));
        let orientation = [q.w, q.i, q.j, q.k];
        let middle = (tip0 + end0) * 0.5;
        let at = surface.nearest(middle.into()).ok_or(BuiltinPathError::NoSurface)?;
        let up = Vector3::from(surface.normal_at(&at)) * lift_m;
        let mut key = |t: f64, tip: Vector3<f64>, end: Vector3<f64>| {
            keys.push((t, tip.into(), 0.0));
            blades.push(BladeKey {
                end_m: end.into(),
                orientation,
            });
        };
        key(t, tip0 + up, end0 + up);
        t += 0.5;
        for k in 0..n {
            let (tip, end) = pos(k);
            key(t + seconds_per_cut * k as f64 / (n - 1) as f64, tip, end);
        }
        t += seconds_per_cut + 0.5;
        let (tip, end) = pos(n - 1);
        key(t, tip + up, end + up);
        t += 0.25;
    }
    Ok(Trajectory::new(keys)?.with_blades(blades)?)
}

/// The built-in grasp of a tearing scene: the jaws, open, come to `centre` (the grasp: the
/// nodes the scene's load acts on) in 0.3 s, close in 0.2 s, pull along `direction` (the
/// load's) by `pull_m` in `seconds`, hold 0.5 s, open in 0.2 s and wait 0.5 s.
pub fn builtin_grasp(centre: [f64; 3], direction: [f64; 3], pull_m: f64, seconds: f64) -> Result<Trajectory, BuiltinPathError> {
    let len = direction.iter().map(|x| x * x).sum::<f64>().sqrt();
    if !(len > 0.0 && len.is_finite()) {
        return Err(BuiltinPathError::NoDirection);
    }
    let at = |d: f64| [0, 1, 2].map(|k| centre[k] + d * direction[k] / len);
    let t1 = 0.5 + seconds;
    Ok(Trajectory::new(vec![
        (0.0, at(0.0), 0.0),
        (0.3, at(0.0), 0.0),
        (0.5, at(0.0), 1.0),
        (t1, at(pull_m), 1.0),
        (t1 + 0.5, at(pull_m), 1.0),
        (t1 + 0.7, at(pull_m), 0.0),
        (t1 + 1.2, at(pull_m), 0.0),
    ])?)
}

/// The built-in palpation of an organ: a probe of radius `radius_m` comes down on the
/// middle of the accessible surface along its normal, presses `depth_m` deep, holds,
/// slides `slide_m` along the surface, and lifts off — five seconds in all
/// ([`palpation_frame`] says where).
pub fn builtin_palpation(b: &LoadedBundle, radius_m: f64, depth_m: f64, slide_m: f64) -> Result<Trajectory, BuiltinPathError> {
    let (p, n, t) = palpation_frame(b)?;
    let at = |along_n: f64, along_t: f64| -> [f64; 3] { [0, 1, 2].map(|k| p[k] + along_n * n[k] + along_t * t[k]) };
    let (up, down) = (radius_m + 0.003, radius_m - depth_m);
    Ok(Trajectory::new(vec![
        (0.0, at(up, 0.0), 0.0),
        (1.0, at(down, 0.0), 0.0),
        (1.5, at(down, 0.0), 0.0),
        (3.5, at(down, slide_m), 0.0),
        (4.5, at(up, slide_m), 0.0),
        (5.0, at(up, slide_m), 0.0),
    ])?)
}

/// Where the built-in palpation presses: the "middle" of the accessible surface — the load
/// node nearest the centroid of the load nodes, among those inside the accessible surface
/// (every surface triangle around them accessible: a node on its rim, where it meets a face
/// no tool may touch, would press on that edge; all of them when none is inside) —, the
/// outward normal there (the area-weighted
/// mean of the accessible triangles around it) and the tangent the slide follows (the axis
/// least aligned with the normal, made orthogonal to it): `(point, normal, tangent)`.
pub fn palpation_frame(b: &LoadedBundle) -> Result<([f64; 3], [f64; 3], [f64; 3]), BuiltinPathError> {
    let v = &b.vademecum;
    let loads = v.load_nodes();
    if loads.is_empty() {
        return Err(BuiltinPathError::NoLoadNode);
    }
    let mut c = [0.0; 3];
    for &n in loads {
        for k in 0..3 {
            c[k] += b.nodes[n][k] / loads.len() as f64;
        }
    }
    let d2 = |n: usize| (0..3).map(|k| (b.nodes[n][k] - c[k]).powi(2)).sum::<f64>();
    let inside = |n: usize| {
        b.surface
            .iter()
            .filter(|t| t.contains(&n))
            .all(|t| t.iter().all(|&m| v.is_loadable(m)))
    };
    let nearest = |among: &mut dyn Iterator<Item = usize>| among.min_by(|&a, &bb| d2(a).total_cmp(&d2(bb)));
    let open = |t: &&[usize; 3]| t.iter().all(|&n| v.is_loadable(n));
    let cross = |t: &[usize; 3]| {
        let (p0, p1, p2) = (b.nodes[t[0]], b.nodes[t[1]], b.nodes[t[2]]);
        let (e1, e2) = (
            [p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]],
            [p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2]],
        );
        [
            e1[1] * e2[2] - e1[2] * e2[1],
            e1[2] * e2[0] - e1[0] * e2[2],
            e1[0] * e2[1] - e1[1] * e2[0],
        ]
    };
    let first = nearest(&mut loads.iter().copied()).expect("non-empty");
    let node = if inside(first) {
        Some(first)
    } else {
        nearest(&mut loads.iter().copied().filter(|&n| inside(n)))
    };
    let (point, normal) = match node {
        Some(s) => {
            let mut normal = [0.0; 3];
            for t in b.surface.iter().filter(|t| t.contains(&s)).filter(open) {
                let c = cross(t);
                (0..3).for_each(|k| normal[k] += c[k]);
            }
            (b.nodes[s], normal)
        }
        // no node inside the accessible surface (a plate one cell deep): the centroid of the
        // accessible triangle nearest the middle, and its normal
        None => {
            let centroid = |t: &[usize; 3]| [0, 1, 2].map(|k| (b.nodes[t[0]][k] + b.nodes[t[1]][k] + b.nodes[t[2]][k]) / 3.0);
            let dc = |t: &[usize; 3]| (0..3).map(|k| (centroid(t)[k] - c[k]).powi(2)).sum::<f64>();
            let t = b
                .surface
                .iter()
                .filter(open)
                .min_by(|a, bb| dc(a).total_cmp(&dc(bb)))
                .ok_or(BuiltinPathError::NoAccessibleTriangle)?;
            (centroid(t), cross(t))
        }
    };
    let len = normal.iter().map(|x| x * x).sum::<f64>().sqrt();
    if len.is_nan() || len <= 0.0 {
        return Err(BuiltinPathError::NoNormal);
    }
    let n = normal.map(|x| x / len);
    // a tangent: the axis least aligned with n, made orthogonal to it
    let axis = if n[0].abs() < 0.9 { [1.0, 0.0, 0.0] } else { [0.0, 1.0, 0.0] };
    let dot = axis[0] * n[0] + axis[1] * n[1] + axis[2] * n[2];
    let t = [axis[0] - dot * n[0], axis[1] - dot * n[1], axis[2] - dot * n[2]];
    let tl = t.iter().map(|x| x * x).sum::<f64>().sqrt();
    let t = t.map(|x| x / tl);
    Ok((point, n, t))
}

/// How deep the built-in palpation may press into a large-deformation bundle while every
/// answer comes from the lattice's paths (m): where the paths of the positions around its
/// slide (`slide_m` from the middle, [`palpation_frame`]) end
/// ([`vademecum_engine::rom::palpation::AnmLattice::reach_at`]); `None` without a lattice.
pub fn palpation_reach(b: &LoadedBundle, slide_m: f64) -> Result<Option<f64>, BuiltinPathError> {
    let Some(lattice) = &b.anm else {
        return Ok(None);
    };
    let (p, _, t) = palpation_frame(b)?;
    let points: Vec<[f64; 3]> = (0..=8).map(|k| [0, 1, 2].map(|c| p[c] + slide_m * k as f64 / 8.0 * t[c])).collect();
    Ok(lattice.reach_at(&points))
}
