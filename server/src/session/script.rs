//! Scripted tool paths of headless runs: a [`Trajectory`] sampled at every tick as a probe's
//! tool state, and the built-in palpation of a scene's organ.

use vademecum_bridge::trajectory::Trajectory;
use vademecum_engine::pgd::offline::LoadedBundle;
use vademecum_engine::pipeline::{ToolInput, ToolKind};

/// The probe state of `trajectory` at `t` seconds after its first keyframe.
pub fn tool_at(trajectory: &Trajectory, t: f64) -> ToolInput {
    let s = trajectory.at(t);
    ToolInput {
        kind: ToolKind::Probe,
        position_m: s.position_m,
        velocity_m_s: s.velocity_m_s,
        closure: s.closure,
        ..ToolInput::default()
    }
}

/// The built-in palpation of an organ: a probe of radius `radius_m` comes down on the
/// middle of the accessible surface along its normal, presses `depth_m` deep, holds,
/// slides `slide_m` along the surface, and lifts off — five seconds in all.
///
/// "Middle" is the load node nearest the centroid of the load nodes; the normal is the
/// area-weighted mean of the accessible triangles around it.
pub fn builtin_palpation(b: &LoadedBundle, radius_m: f64, depth_m: f64, slide_m: f64) -> Result<Trajectory, String> {
    let v = &b.vademecum;
    let loads = v.load_nodes();
    if loads.is_empty() {
        return Err("the bundle has no load node to palpate".into());
    }
    let mut c = [0.0; 3];
    for &n in loads {
        for k in 0..3 {
            c[k] += b.nodes[n][k] / loads.len() as f64;
        }
    }
    let d2 = |n: usize| (0..3).map(|k| (b.nodes[n][k] - c[k]).powi(2)).sum::<f64>();
    let s = *loads.iter().min_by(|&&a, &&bb| d2(a).total_cmp(&d2(bb))).expect("non-empty");
    let mut normal = [0.0; 3];
    for t in b.surface.iter().filter(|t| t.contains(&s) && t.iter().all(|&n| v.is_loadable(n))) {
        let (p0, p1, p2) = (b.nodes[t[0]], b.nodes[t[1]], b.nodes[t[2]]);
        let (e1, e2) = (
            [p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]],
            [p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2]],
        );
        normal[0] += e1[1] * e2[2] - e1[2] * e2[1];
        normal[1] += e1[2] * e2[0] - e1[0] * e2[2];
        normal[2] += e1[0] * e2[1] - e1[1] * e2[0];
    }
    let len = normal.iter().map(|x| x * x).sum::<f64>().sqrt();
    if len.is_nan() || len <= 0.0 {
        return Err("the middle of the accessible surface has no accessible triangle around it".into());
    }
    let n = normal.map(|x| x / len);
    // a tangent: the axis least aligned with n, made orthogonal to it
    let axis = if n[0].abs() < 0.9 { [1.0, 0.0, 0.0] } else { [0.0, 1.0, 0.0] };
    let dot = axis[0] * n[0] + axis[1] * n[1] + axis[2] * n[2];
    let t = [axis[0] - dot * n[0], axis[1] - dot * n[1], axis[2] - dot * n[2]];
    let tl = t.iter().map(|x| x * x).sum::<f64>().sqrt();
    let t = t.map(|x| x / tl);
    let p = b.nodes[s];
    let at = |along_n: f64, along_t: f64| -> [f64; 3] { [0, 1, 2].map(|k| p[k] + along_n * n[k] + along_t * t[k]) };
    let (up, down) = (radius_m + 0.003, radius_m - depth_m);
    Trajectory::new(vec![
        (0.0, at(up, 0.0), 0.0),
        (1.0, at(down, 0.0), 0.0),
        (1.5, at(down, 0.0), 0.0),
        (3.5, at(down, slide_m), 0.0),
        (4.5, at(up, slide_m), 0.0),
        (5.0, at(up, slide_m), 0.0),
    ])
}
