//! Every conversion between the wire contract (`vademecum.v1`) and engine/session types,
//! and the validation that goes with it.

use vademecum_engine::pipeline::{GraspSite, ToolInput, ToolKind};
use vademecum_engine::scene::schema::ToolSpec;
use vademecum_proto::v1 as pb;

use crate::registry::{Entry, SceneSource};
use crate::session::{Answer, Frame, SurfaceGeometry};

fn vec3(v: Option<&pb::Vec3>) -> [f64; 3] {
    v.map_or([0.0; 3], |v| [v.x, v.y, v.z])
}

fn pb_vec3(v: [f64; 3]) -> pb::Vec3 {
    pb::Vec3 { x: v[0], y: v[1], z: v[2] }
}

/// Why a tool state's `tool` cannot be moved (the stream ends with INVALID_ARGUMENT).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ToolNameError {
    /// The scene has no tool of that name.
    #[error("the session's scene has no tool named '{name}' (its tools: {known})")]
    Unknown {
        /// The name asked for (capped).
        name: String,
        /// The scene's tool names.
        known: String,
    },
    /// The named tool is of another kind than the state says.
    #[error("tool '{name}' is a {is:?}, but the tool state says {says:?}")]
    OtherKind {
        /// The tool's name.
        name: String,
        /// Its kind in the scene.
        is: ToolKind,
        /// The state's kind.
        says: ToolKind,
    },
}

/// A tool state as the tick reads it, its `tool` name resolved among the scene's `tools`
/// (its index; an empty name is tool 0, the session's one tool at a time, whatever its kind;
/// a named tool with an unspecified kind takes the tool's). Values are not checked here: the
/// pipeline answers a non-finite or out-of-range state with zero force and the
/// REJECTED_INPUT event, so a bad sample from a device never ends a stream.
pub fn tool_input(t: &pb::ToolState, tools: &[ToolSpec]) -> Result<ToolInput, ToolNameError> {
    let mut input = tool_state(t);
    if t.tool.is_empty() {
        return Ok(input);
    }
    let Some(index) = tools.iter().position(|s| s.name() == t.tool) else {
        return Err(ToolNameError::Unknown {
            name: crate::error::clip(&t.tool),
            known: tools.iter().map(|s| format!("'{}'", s.name())).collect::<Vec<_>>().join(", "),
        });
    };
    let is = crate::session::tool_kind(&tools[index]);
    if t.kind == pb::ToolKind::Unspecified as i32 {
        input.kind = is;
    } else if input.kind != is {
        return Err(ToolNameError::OtherKind {
            name: crate::error::clip(&t.tool),
            is,
            says: input.kind,
        });
    }
    input.tool = index;
    Ok(input)
}

/// A tool state's values, for tool 0.
fn tool_state(t: &pb::ToolState) -> ToolInput {
    ToolInput {
        tool: 0,
        kind: match pb::ToolKind::try_from(t.kind) {
            Ok(pb::ToolKind::Scalpel) => ToolKind::Scalpel,
            Ok(pb::ToolKind::Grasper) => ToolKind::Grasper,
            Ok(pb::ToolKind::Probe) | Ok(pb::ToolKind::Unspecified) => ToolKind::Probe,
            _ => ToolKind::Other,
        },
        position_m: vec3(t.position_m.as_ref()),
        velocity_m_s: vec3(t.velocity_m_s.as_ref()),
        closure: t.closure,
        orientation: match &t.orientation {
            None => [1.0, 0.0, 0.0, 0.0],
            Some(q) if [q.w, q.x, q.y, q.z] == [0.0; 4] => [1.0, 0.0, 0.0, 0.0],
            Some(q) => [q.w, q.x, q.y, q.z],
        },
        blade_end_m: vec3(t.blade_end_m.as_ref()),
    }
}

/// A contact on the wire.
fn pb_contact(c: &vademecum_engine::pipeline::Contact) -> pb::Contact {
    pb::Contact {
        organ: c.organ as u32,
        point_m: Some(pb_vec3(c.point_m)),
        depth_m: c.depth_m,
        proxy_m: Some(pb_vec3(c.proxy_m)),
    }
}

/// The response to one tool state.
pub fn tool_response(a: &Answer) -> pb::ToolResponse {
    pb::ToolResponse {
        seq: a.seq,
        client_time_us: a.client_time_us,
        force_n: Some(pb_vec3(a.state.force_n)),
        contact: a.state.contact.as_ref().map(pb_contact),
        events: a.state.events.0,
        server_received_us: a.received_us,
        server_answered_us: a.answered_us,
        tick: a.tick,
        blade: a.state.blade.map(|b| pb::BladeForce {
            perpendicular_n: Some(pb_vec3(b.perpendicular_n)),
            parallel_n: Some(pb_vec3(b.parallel_n)),
            cutting: b.cutting,
        }),
        force_error_n: a.state.force_error_n,
    }
}

/// The scene of a create request.
pub fn scene_source(r: &pb::CreateSessionRequest) -> Result<SceneSource, crate::error::ServerError> {
    use pb::create_session_request::Scene as S;
    match &r.scene {
        Some(S::SceneToml(t)) => Ok(SceneSource::Inline(t.clone())),
        Some(S::ScenePath(p)) => Ok(SceneSource::Path(p.clone())),
        Some(S::Builtin(b)) => Ok(SceneSource::Builtin(b.clone())),
        None => Err(crate::error::ServerError::Invalid(
            "set one of scene_toml, scene_path or builtin".into(),
        )),
    }
}

fn f32_bytes(v: impl IntoIterator<Item = f32>) -> Vec<u8> {
    v.into_iter().flat_map(f32::to_le_bytes).collect()
}

/// The first message of a viewing stream: the reference surfaces.
pub fn geometry_frame(g: &SurfaceGeometry) -> pb::Frame {
    pb::Frame {
        geometry: Some(pb::Geometry {
            organs: g
                .organs
                .iter()
                .map(|o| pb::SurfaceMesh {
                    organ: o.name.clone(),
                    positions: f32_bytes(o.positions_m.iter().copied()),
                    triangles: o.triangles.iter().flat_map(|t| t.to_le_bytes()).collect(),
                    node_count: o.nodes.len() as u32,
                    accessible: o.accessible.clone(),
                })
                .collect(),
        }),
        ..Default::default()
    }
}

/// A displacement frame, number `seq` of its stream.
pub fn frame(f: &Frame, seq: u64) -> pb::Frame {
    pb::Frame {
        seq,
        session_frame: f.seq,
        heartbeat: false,
        tick: f.tick,
        time_s: f.time_s,
        geometry: None,
        organs: f
            .displacements_m
            .iter()
            .zip(&f.cuts)
            .zip(&f.damage)
            .enumerate()
            .map(|(o, ((d, cut), damage))| pb::OrganDisplacement {
                displacements: f32_bytes(d.iter().copied()),
                visual: f.visual.as_ref().filter(|v| v.organ == o).map(|v| pb::VisualSurface {
                    revision: v.revision,
                    vertex_count: (v.positions_m.len() / 3) as u32,
                    positions: f32_bytes(v.positions_m.iter().copied()),
                    triangles: v.triangles.iter().flat_map(|t| t.to_le_bytes()).collect(),
                    displacements: f32_bytes(v.displacements_m.iter().copied()),
                }),
                partial_cut: f.partial.as_ref().filter(|p| p.organ == o).map(|p| pb::PartialCut {
                    seq: p.seq,
                    positions: f32_bytes(p.positions_m.iter().copied()),
                    displacements: f32_bytes(p.displacements_m.iter().copied()),
                }),
                damage: damage.as_ref().map(|t| pb::TissueDamage {
                    cell_damage: f32_bytes(t.cell_damage.iter().copied()),
                    triangle_damage: f32_bytes(t.triangle_damage.iter().copied()),
                    torn: t.torn,
                    grasped: t.grasped,
                    dissipated_j: t.dissipated_j,
                }),
                cut: cut.as_ref().map(|c| pb::CutWalls {
                    revision: c.revision,
                    vertex_count: c.side.len() as u32,
                    positions: f32_bytes(c.positions_m.iter().copied()),
                    triangles: c.triangles.iter().flat_map(|t| t.to_le_bytes()).collect(),
                    side: c.side.to_vec(),
                    displacements: f32_bytes(c.displacements_m.iter().copied()),
                }),
            })
            .collect(),
        force_n: Some(pb_vec3(f.force_n)),
        contact: f.contact.as_ref().map(pb_contact),
        tool_m: f.tool_m.map(pb_vec3),
        tools: f
            .tools
            .iter()
            .map(|t| pb::ToolView {
                name: t.name.clone(),
                tool_m: t.tool_m.map(pb_vec3),
                force_n: Some(pb_vec3(t.force_n)),
                contact: t.contact.as_ref().map(pb_contact),
            })
            .collect(),
        message: 0,
    }
}

/// A heartbeat: nothing new since the stream's frame `seq` (session frame `f.seq`); the
/// session is at `tick`.
pub fn heartbeat(f: &Frame, seq: u64, tick: u64, time_s: f64) -> pb::Frame {
    pb::Frame {
        seq,
        session_frame: f.seq,
        heartbeat: true,
        tick,
        time_s,
        force_n: Some(pb_vec3(f.force_n)),
        ..Default::default()
    }
}

/// What GetSession and friends return.
pub fn session_info(e: &Entry) -> pb::SessionInfo {
    let s = &e.session;
    pb::SessionInfo {
        session_id: s.id().to_string(),
        scene: s.scene().spec.scene.name.clone(),
        label: e.label.clone(),
        organs: s.scene().spec.organs.iter().map(|o| o.name.clone()).collect(),
        effects: s.effects().iter().map(|x| x.to_string()).collect(),
        tick_rate_hz: 1.0 / s.config().period.as_secs_f64(),
        stats: Some(session_stats(e)),
        haptic_channel: s.config().haptic.as_ref().map(|h| h.channel.name().to_string()).unwrap_or_default(),
        tools: {
            let channels = match &s.config().haptic {
                Some(h) => crate::session::tool_channels(&h.channel, s.scene()).unwrap_or_default(),
                None => Vec::new(),
            };
            // in the scene's tool order
            let channel = |k: usize| channels.get(k).map(|(_, c)| c.name().to_string()).unwrap_or_default();
            s.scene()
                .spec
                .tools
                .iter()
                .enumerate()
                .map(|(k, t)| pb::ToolInfo {
                    haptic_channel: channel(k),
                    ..tool_info(t, s.grasp_sites())
                })
                .collect()
        },
        organ_info: s
            .geometry()
            .organs
            .iter()
            .map(|o| pb::OrganInfo {
                name: o.name.clone(),
                bounds_min_m: Some(pb_vec3(o.bounds.min)),
                bounds_max_m: Some(pb_vec3(o.bounds.max)),
                accessible_min_m: o.accessible_bounds.map(|b| pb_vec3(b.min)),
                accessible_max_m: o.accessible_bounds.map(|b| pb_vec3(b.max)),
                accessible_triangles: o.accessible_triangles as u32,
            })
            .collect(),
        workspace_min_m: Some(pb_vec3(s.workspace().min)),
        workspace_max_m: Some(pb_vec3(s.workspace().max)),
        // it lives here; a front door that placed it elsewhere sets it
        redirect: None,
    }
}

/// What a client needs to know of a scene's tool; a grasper's sites are the session's `grasp`.
fn tool_info(t: &ToolSpec, grasp: &[GraspSite]) -> pb::ToolInfo {
    use vademecum_engine::pipeline::SCALPEL_TIP_FRACTION;
    let (kind, radius_m, max_force_n) = match t {
        ToolSpec::Probe { radius, max_force, .. } => (pb::ToolKind::Probe, *radius, *max_force),
        ToolSpec::Scalpel {
            blade_length, max_force, ..
        } => (pb::ToolKind::Scalpel, SCALPEL_TIP_FRACTION * blade_length, *max_force),
        ToolSpec::Grasper { max_force, .. } => (pb::ToolKind::Grasper, 0.0, *max_force),
    };
    let (blade_length_m, cut_force_n) = match t {
        ToolSpec::Scalpel {
            blade_length, cut_force, ..
        } => (*blade_length, *cut_force),
        _ => (0.0, 0.0),
    };
    let (jaw_width_m, grasp_sites) = match t {
        ToolSpec::Grasper { jaw_width, .. } => (
            *jaw_width,
            grasp
                .iter()
                .map(|g| pb::GraspSite {
                    organ: g.organ as u32,
                    centre_m: Some(pb_vec3(g.centre_m)),
                    pull_direction: Some(pb_vec3(g.pull_direction)),
                })
                .collect(),
        ),
        _ => (0.0, Vec::new()),
    };
    pb::ToolInfo {
        name: t.name().to_string(),
        kind: kind as i32,
        radius_m,
        max_force_n,
        blade_length_m,
        cut_force_n,
        jaw_width_m,
        grasp_sites,
        haptic_channel: String::new(),
    }
}

/// Live statistics of a session.
pub fn session_stats(e: &Entry) -> pb::SessionStats {
    use std::sync::atomic::Ordering::Relaxed;
    let st = e.session.stats().snapshot();
    let b = st.bridge.unwrap_or_default();
    let tools = &e.session.scene().spec.tools;
    let memory = e.session.memory();
    pb::SessionStats {
        ticks: st.ticks,
        deadline_misses: st.misses,
        answered: st.answered,
        rejected: st.rejected,
        dropped: st.dropped,
        frames: st.frames,
        tick_work_p50_us: st.work_us.p50,
        tick_work_p99_us: st.work_us.p99,
        response_p50_us: st.response_us.p50,
        response_p99_us: st.response_us.p99,
        interacting_clients: e.interacting.load(Relaxed),
        viewers: e.viewers.load(Relaxed),
        haptic_answered: st.haptic_answered,
        bridge_latency_p50_us: b.latency_us.p50,
        bridge_latency_p99_us: b.latency_us.p99,
        bridge_deadline_misses: b.deadline_misses,
        bridge_watchdog_ticks: b.watchdog_ticks,
        bridge_input_rejections: b.input_rejections(),
        fidelity_fallbacks: st.fallbacks,
        fidelity_reduced: e.session.stats().reduced.load(Relaxed),
        reduced_ticks: st.reduced_ticks,
        bridges: st
            .bridges
            .iter()
            .map(|(tool, b)| pb::BridgeStats {
                tool: tools.get(*tool).map_or(String::new(), |t| t.name().to_string()),
                latency_p50_us: b.latency_us.p50,
                latency_p99_us: b.latency_us.p99,
                deadline_misses: b.deadline_misses,
                watchdog_ticks: b.watchdog_ticks,
                input_rejections: b.input_rejections(),
            })
            .collect(),
        memory_bytes: memory.total(),
        memory: memory
            .parts
            .into_iter()
            .map(|(part, bytes)| pb::MemoryPart { part, bytes })
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;
    use crate::session::frames::{OrganSurface, PartialFrame, SurfaceGeometry, VisualFrame};

    fn two_organs() -> SurfaceGeometry {
        let organ = |name: &str| OrganSurface {
            name: name.into(),
            nodes: vec![0, 1, 2],
            positions_m: vec![0.0; 9],
            triangles: vec![0, 1, 2],
            accessible: vec![1; 3],
            bounds: vademecum_engine::contact::Bounds {
                min: [0.0; 3],
                max: [1.0; 3],
            },
            accessible_bounds: None,
            accessible_triangles: 1,
        };
        SurfaceGeometry {
            organs: vec![organ("a"), organ("b")],
            tools: vec!["probe".into()],
        }
    }

    #[test]
    fn a_frame_carries_the_visual_surface_on_its_organ_only() {
        let g = two_organs();
        let mut f = Frame::rest(&g);
        assert!(frame(&f, 1).organs.iter().all(|o| o.visual.is_none()), "no visual mesh: unset");
        f.visual = Some(VisualFrame {
            organ: 1,
            revision: 3,
            positions_m: Arc::from(vec![0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]),
            triangles: Arc::from(vec![0u32, 2, 1, 0, 1, 3, 1, 2, 3, 0, 3, 2]),
            displacements_m: vec![0.5; 12],
        });
        let pb = frame(&f, 1);
        assert!(pb.organs[0].visual.is_none());
        let v = pb.organs[1].visual.as_ref().expect("organ 1 carries it");
        assert_eq!((v.revision, v.vertex_count), (3, 4));
        let floats = |b: &[u8]| {
            b.chunks_exact(4)
                .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                .collect::<Vec<_>>()
        };
        assert_eq!(floats(&v.positions)[3], 1.0);
        assert_eq!(floats(&v.displacements), vec![0.5; 12]);
        let tris: Vec<u32> = v
            .triangles
            .chunks_exact(4)
            .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        assert_eq!(tris, vec![0, 2, 1, 0, 1, 3, 1, 2, 3, 0, 3, 2]);
    }

    #[test]
    fn a_frame_carries_the_partial_cut_on_its_organ_only() {
        let g = two_organs();
        let mut f = Frame::rest(&g);
        assert!(frame(&f, 1).organs.iter().all(|o| o.partial_cut.is_none()), "none: unset");
        f.partial = Some(PartialFrame {
            organ: 0,
            seq: 7,
            positions_m: Arc::from(vec![0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]),
            displacements_m: vec![0.25; 9],
        });
        let pb = frame(&f, 1);
        assert!(pb.organs[1].partial_cut.is_none());
        let p = pb.organs[0].partial_cut.as_ref().expect("organ 0 carries it");
        assert_eq!(p.seq, 7);
        assert_eq!((p.positions.len(), p.displacements.len()), (36, 36));
        assert_eq!(
            f32::from_le_bytes([p.positions[12], p.positions[13], p.positions[14], p.positions[15]]),
            1.0
        );
        assert_eq!(
            f32::from_le_bytes([p.displacements[0], p.displacements[1], p.displacements[2], p.displacements[3]]),
            0.25
        );
    }
}
