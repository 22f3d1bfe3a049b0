//! The tick under what devices and clients send: the built-in organ's palpation pipeline (its
//! PGD vademecum built, written and loaded back as a session's) fed a NaN or an infinity in
//! every field of a pressing tool state, a tool that jumps 10 cm in one tick, every limit of the
//! tool state at its edge and just past it, and a probe pressed where the vademecum has no load
//! states (the fixed underside). A rejected state is the typed diagnostic (`REJECTED_INPUT`,
//! zero force) and must leave the session answering the next valid state as before.

use std::sync::{Arc, Mutex};

use super::{Case, Expect, Outcome, Size, builtin_at, diagnostic, outcome, relative, session_bundle};
use crate::bundle::LoadedBundle;
use crate::offline;
use crate::pipeline::{Events, MAX_TOOL_SPEED_M_S, Pipeline, QUATERNION_NORM_TOLERANCE, TickState, ToolInput};
use crate::scene::Scene;

/// The built-in organ, coarser at reduced size.
fn organ_scene(size: Size) -> Result<Scene, Outcome> {
    builtin_at("organ", size, ["[8, 5, 3]", "[16, 10, 6]"])
}

/// The organ's bundle for `size`, built once per process and size (a few seconds), written
/// and loaded back as a session's.
fn organ_bundle(scene: &Scene, size: Size) -> Result<Arc<LoadedBundle>, Outcome> {
    static BUILT: Mutex<Vec<(Size, Arc<LoadedBundle>)>> = Mutex::new(Vec::new());
    session_bundle(&BUILT, scene, size)
}

/// A pipeline of the organ and a probe state pressing 2 mm into the middle of its accessible
/// (upper) surface, straight down.
fn pressing(size: Size) -> Result<(Pipeline, ToolInput, Arc<LoadedBundle>, f64), Outcome> {
    let scene = organ_scene(size)?;
    let b = organ_bundle(&scene, size)?;
    let pipe = Pipeline::for_scene(&scene, std::slice::from_ref(&b)).map_err(diagnostic)?;
    let top = top_load_node(&b)?;
    let r = offline::probe_radius(&scene);
    let p = b.nodes[top];
    let tool = ToolInput {
        position_m: [p[0], p[1], p[2] + r - 0.002],
        ..ToolInput::default()
    };
    Ok((pipe, tool, b, r))
}

/// The highest load node: the middle of the organ's upper surface.
fn top_load_node(b: &LoadedBundle) -> Result<usize, Outcome> {
    b.vademecum
        .load_nodes()
        .iter()
        .copied()
        .max_by(|&a, &c| b.nodes[a][2].total_cmp(&b.nodes[c][2]))
        .ok_or_else(|| Outcome::Broken("the vademecum has no load nodes".into()))
}

fn norm(f: [f64; 3]) -> f64 {
    f.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// Whether a tick's answer is finite and within the pipeline's force limit.
fn bounded(pipe: &Pipeline, s: &TickState) -> bool {
    s.force_n.iter().all(|f| f.is_finite()) && norm(s.force_n) <= pipe.max_force_n() * (1.0 + 1e-12)
}

/// The same valid state after a poisoned one answers as it did before it (to rounding).
fn unchanged(before: &TickState, after: &TickState) -> bool {
    relative(norm(after.force_n), norm(before.force_n)) < 1e-9
}

fn poisoned_inputs(size: Size) -> Outcome {
    outcome(|| {
        let (mut pipe, tool, _, _) = pressing(size)?;
        let before = pipe.tick(&tool);
        if before.contact.is_none() || !bounded(&pipe, &before) {
            return Ok(Outcome::Broken(format!("the pressing state answers {:?}", before.force_n)));
        }
        let mut rejected = 0;
        for field in 0..14 {
            for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
                let mut t = tool;
                match field {
                    0..3 => t.position_m[field] = bad,
                    3..6 => t.velocity_m_s[field - 3] = bad,
                    6..10 => t.orientation[field - 6] = bad,
                    10..13 => t.blade_end_m[field - 10] = bad,
                    _ => t.closure = bad,
                }
                let s = pipe.tick(&t);
                if !s.events.has(Events::REJECTED_INPUT) || s.force_n != [0.0; 3] {
                    return Ok(Outcome::Broken(format!(
                        "field {field} = {bad}: answered {:?} without rejecting it",
                        s.force_n
                    )));
                }
                let again = pipe.tick(&tool);
                if !unchanged(&before, &again) {
                    return Ok(Outcome::Broken(format!(
                        "after field {field} = {bad}: {:?} N, before {:?} N",
                        again.force_n, before.force_n
                    )));
                }
                rejected += 1;
            }
        }
        Ok(Outcome::Diagnostic(format!(
            "{rejected} of 42 poisoned states rejected (REJECTED_INPUT, zero force); the next valid state answers {:.3} N as before",
            norm(before.force_n)
        )))
    })
}

fn jump(size: Size) -> Outcome {
    outcome(|| {
        let (mut pipe, tool, _, _) = pressing(size)?;
        let before = pipe.tick(&tool);
        let moved = |axis: usize, by: f64| {
            let mut t = tool;
            t.position_m[axis] += by;
            t
        };
        // 3 cm into the 5 cm thick organ, then through it and out below, then off its edge
        let into = pipe.tick(&moved(2, -0.03));
        pipe.tick(&tool);
        let through = pipe.tick(&moved(2, -0.1));
        pipe.tick(&tool);
        let side = pipe.tick(&moved(0, 0.1));
        let back = pipe.tick(&tool);
        for (what, s) in [
            ("3 cm in", &into),
            ("10 cm down", &through),
            ("10 cm aside", &side),
            ("back", &back),
        ] {
            if !bounded(&pipe, s) {
                return Ok(Outcome::Broken(format!("{what}: {:?} N", s.force_n)));
            }
        }
        if !unchanged(&before, &back) {
            return Ok(Outcome::Broken(format!(
                "back at the start: {:.4} N, before {:.4} N",
                norm(back.force_n),
                norm(before.force_n)
            )));
        }
        Ok(Outcome::bounded(format!(
            "3 cm in: {:.2} N{}; 10 cm down, through and out: {:.2} N; 10 cm aside, off the edge: {:.2} N; back: {:.3} N as before (limit {} N)",
            norm(into.force_n),
            if into.events.has(Events::FORCE_SATURATED) {
                " (saturated)"
            } else {
                ""
            },
            norm(through.force_n),
            norm(side.force_n),
            norm(back.force_n),
            pipe.max_force_n()
        )))
    })
}

fn edges(size: Size) -> Outcome {
    outcome(|| {
        let (mut pipe, tool, _, _) = pressing(size)?;
        let ws = pipe.workspace();
        let speed = |v: f64| {
            let mut t = tool;
            t.velocity_m_s = [v, 0.0, 0.0];
            t
        };
        let closure = |c: f64| {
            let mut t = tool;
            t.closure = c;
            t
        };
        let quaternion = |n: f64| {
            let mut t = tool;
            t.orientation = [n, 0.0, 0.0, 0.0];
            t
        };
        let at_x = |x: f64| {
            let mut t = tool;
            t.position_m[0] = x;
            t
        };
        let q = QUATERNION_NORM_TOLERANCE;
        let states = [
            ("speed at the limit", speed(MAX_TOOL_SPEED_M_S), true),
            ("speed past it", speed(MAX_TOOL_SPEED_M_S * (1.0 + 1e-9)), false),
            ("closure 0", closure(0.0), true),
            ("closure 1", closure(1.0), true),
            ("closure past 1", closure(1.0 + 1e-9), false),
            ("closure below 0", closure(-1e-9), false),
            ("quaternion norm 1 + 0.999 tol", quaternion(1.0 + 0.999 * q), true),
            ("quaternion norm 1 − 0.999 tol", quaternion(1.0 - 0.999 * q), true),
            ("quaternion norm past tol", quaternion(1.0 + 1.001 * q), false),
            ("zero quaternion", quaternion(0.0), false),
            ("at the workspace's edge", at_x(ws.max[0] - 1e-9), true),
            ("past the workspace's edge", at_x(ws.max[0] + 1e-6), false),
        ];
        for (what, t, accepted) in states {
            let s = pipe.tick(&t);
            if s.events.has(Events::REJECTED_INPUT) == accepted || !bounded(&pipe, &s) {
                return Ok(Outcome::Broken(format!(
                    "{what}: {} with {:?} N",
                    if accepted { "rejected" } else { "accepted" },
                    s.force_n
                )));
            }
        }
        Ok(Outcome::bounded(format!(
            "{} states at each limit accepted with a bounded force, each just past it rejected",
            states.len()
        )))
    })
}

fn outside_accessible(size: Size) -> Outcome {
    outcome(|| {
        let (mut pipe, _, b, r) = pressing(size)?;
        let loads = b.vademecum.load_nodes();
        // the lowest surface node: on the underside, which no load state covers
        let low = b
            .surface
            .iter()
            .flatten()
            .copied()
            .min_by(|&a, &c| b.nodes[a][2].total_cmp(&b.nodes[c][2]))
            .ok_or_else(|| Outcome::Broken("the organ has no surface".into()))?;
        if loads.contains(&low) {
            return Ok(Outcome::Broken("the underside is loadable: not the case meant".into()));
        }
        let p = b.nodes[low];
        let mut last = TickState::default();
        // from below, up to 3 mm deep
        for k in 0..=30 {
            let tool = ToolInput {
                position_m: [p[0], p[1], p[2] - r - 0.001 + 0.004 * k as f64 / 30.0],
                ..ToolInput::default()
            };
            last = pipe.tick(&tool);
            if !bounded(&pipe, &last) {
                return Ok(Outcome::Broken(format!("{:?} N", last.force_n)));
            }
        }
        let Some(c) = last.contact else {
            return Ok(Outcome::Broken("no contact pressed 3 mm into the underside".into()));
        };
        Ok(Outcome::bounded(format!(
            "{:.3} N at {:.1} mm deep, {:.0} % of it on the deformable tissue (nearest load states), the rest on the support",
            norm(last.force_n),
            1e3 * c.depth_m,
            100.0 * c.loadable
        )))
    })
}

/// The pressing organ's pipeline with a second probe (`left`, tool 1) beside its own, and the
/// pressing state.
fn two_probes(size: Size) -> Result<(Pipeline, ToolInput, Arc<LoadedBundle>), Outcome> {
    let (_, tool, b, _) = pressing(size)?;
    let scene = organ_scene(size)?;
    let text = format!(
        "{}\n[[tools]]\nkind = \"probe\"\nname = \"left\"\nradius = {}\n",
        scene.source,
        offline::probe_radius(&scene)
    );
    let two = Scene::from_toml(&text, "<hard case: two probes>").map_err(diagnostic)?;
    // the build reads the first probe only: the organ's bundle serves
    let pipe = Pipeline::for_scene(&two, std::slice::from_ref(&b)).map_err(diagnostic)?;
    Ok((pipe, tool, b))
}

/// Two probes pressing 2 mm in at the same spot: the contacts are not independent (a
/// singular system); the shallower lets go and the deeper takes the load, so the pair feels
/// what one probe would.
fn same_spot(size: Size) -> Outcome {
    outcome(|| {
        let (mut pipe, tool, _) = two_probes(size)?;
        let alone = pipe.tick(&tool);
        pipe.reset();
        let mut states = [TickState::default(); 2];
        pipe.tick_tools(&[tool, ToolInput { tool: 1, ..tool }], &mut states);
        if !states.iter().all(|s| bounded(&pipe, s)) {
            return Ok(Outcome::Broken(format!("{:?} {:?} N", states[0].force_n, states[1].force_n)));
        }
        let total = [0, 1, 2].map(|k| states[0].force_n[k] + states[1].force_n[k]);
        let error =
            relative(norm(total), norm(alone.force_n)).max(norm([0, 1, 2].map(|k| total[k] - alone.force_n[k])) / norm(alone.force_n));
        Ok(Outcome::answer(
            format!(
                "{:.3} N and {:.3} N (one probe alone: {:.3} N)",
                norm(states[0].force_n),
                norm(states[1].force_n),
                norm(alone.force_n)
            ),
            error,
        ))
    })
}

/// Two probes 9 mm apart (their 4 mm tips do not overlap), each pressing 2 mm in at a load
/// node — each on the other's triangle or load patch, where the compliances between them are the exact local
/// blocks: both answers finite and bounded, neither pulling, together at least what one probe
/// alone needs and at most twice it.
fn on_the_others_patch(size: Size) -> Outcome {
    outcome(|| {
        let (mut pipe, tool, b) = two_probes(size)?;
        let alone = pipe.tick(&tool);
        pipe.reset();
        // the load node nearest to 9 mm (sideways) from the pressed point, pressed as deep
        let p = tool.position_m;
        let sideways = |n: usize| ((b.nodes[n][0] - p[0]).powi(2) + (b.nodes[n][1] - p[1]).powi(2)).sqrt();
        let near = b
            .vademecum
            .load_nodes()
            .iter()
            .copied()
            .min_by(|&x, &y| (sideways(x) - 0.009).abs().total_cmp(&(sideways(y) - 0.009).abs()))
            .ok_or_else(|| Outcome::Broken("no load nodes".into()))?;
        let (pressed, q) = (top_load_node(&b)?, b.nodes[near]);
        let above = p[2] - b.nodes[pressed][2];
        let beside = ToolInput {
            tool: 1,
            position_m: [q[0], q[1], q[2] + above],
            ..tool
        };
        let mut states = [TickState::default(); 2];
        pipe.tick_tools(&[tool, beside], &mut states);
        if !states.iter().all(|s| bounded(&pipe, s)) {
            return Ok(Outcome::Broken(format!("{:?} {:?} N", states[0].force_n, states[1].force_n)));
        }
        // the force on a tool pressing down points up
        if states.iter().any(|s| s.force_n[2] < 0.0) {
            return Ok(Outcome::Broken(format!(
                "a probe pulls: {:?} {:?} N",
                states[0].force_n, states[1].force_n
            )));
        }
        let (one, total) = (
            norm(alone.force_n),
            norm([0, 1, 2].map(|k| states[0].force_n[k] + states[1].force_n[k])),
        );
        if !(one * (1.0 - 1e-9)..=2.0 * one).contains(&total) {
            return Ok(Outcome::Broken(format!("together {total:.3} N, one alone {one:.3} N")));
        }
        Ok(Outcome::bounded(format!(
            "{:.3} N and {:.3} N, together {total:.3} N (one probe alone: {one:.3} N)",
            norm(states[0].force_n),
            norm(states[1].force_n)
        )))
    })
}

pub(super) fn cases() -> Vec<Case> {
    vec![
        Case {
            name: "NaN / ±Inf in every tool-state field",
            method: "palpation pipeline (PGD)",
            expect: Expect::Diagnostic(&["42 of 42 poisoned states rejected"]),
            run: poisoned_inputs,
        },
        Case {
            name: "a tool jumping 10 cm in one tick",
            method: "palpation pipeline (PGD)",
            expect: Expect::FINITE,
            run: jump,
        },
        Case {
            name: "tool-state limits at and past their edge",
            method: "palpation pipeline (PGD)",
            expect: Expect::FINITE,
            run: edges,
        },
        Case {
            name: "two probes on one spot",
            method: "coupled palpation (PGD)",
            expect: Expect::within(1e-9),
            run: same_spot,
        },
        Case {
            name: "a probe on the other probe's load patch",
            method: "coupled palpation (PGD)",
            expect: Expect::FINITE,
            run: on_the_others_patch,
        },
        Case {
            name: "pressed outside the accessible region",
            method: "palpation pipeline (PGD)",
            expect: Expect::FINITE,
            run: outside_accessible,
        },
    ]
}
