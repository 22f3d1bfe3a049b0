//! Displacement frames for viewers: the reference surface of every organ (sent once), and
//! per frame the displacement of its nodes, computed on the frame thread from the latest
//! tick state (see the [module docs](super)).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::SyncSender;
use std::thread::Thread;
use std::time::{Duration, Instant};

use tokio::sync::watch;
use vademecum_engine::bundle::LoadedBundle;
use vademecum_engine::contact::Bounds;
use vademecum_engine::damage::online::TearOffline;
use vademecum_engine::pgd::vademecum::NodeMajorField;
use vademecum_engine::pipeline::Contact;
use vademecum_engine::pipeline::corotational::CorotationalDeformation;
use vademecum_engine::pipeline::cutting::{CutPicture, CutStatus};
use vademecum_engine::pipeline::{TearPicture, TearPictures};
use vademecum_engine::scene::Scene;

use super::demand::FrameDemand;
use super::stats::TickStats;
use super::tick::{Latest, Lockstep};
use super::workers::{PlaceError, Placed, Poll, Polled, Pool, PoolConfig};

/// The reference surface of one organ.
#[derive(Debug, Clone, PartialEq)]
pub struct OrganSurface {
    /// Organ name.
    pub name: String,
    /// Mesh nodes on the surface, sorted (frame arrays follow this order).
    pub nodes: Vec<usize>,
    /// Their reference positions (m), 3 per node.
    pub positions_m: Vec<f32>,
    /// Surface triangles as indices into `nodes`, 3 per triangle, outward.
    pub triangles: Vec<u32>,
    /// Per node of `nodes`, 1 where the vademecum can load it, else 0.
    pub accessible: Vec<u8>,
    /// Box of the surface.
    pub bounds: Bounds,
    /// Box of the accessible triangles (`None`: there are none).
    pub accessible_bounds: Option<Bounds>,
    /// Number of accessible triangles (all three nodes loadable).
    pub accessible_triangles: usize,
}

/// The reference surfaces of a session's organs.
#[derive(Debug, Clone, PartialEq)]
pub struct SurfaceGeometry {
    /// One per organ, in scene order.
    pub organs: Vec<OrganSurface>,
    /// The scene's tool names, in scene order (what [`ToolFrame::name`] says).
    pub tools: Vec<String>,
}

impl SurfaceGeometry {
    /// The boundary surfaces stored in the bundles.
    pub fn of(scene: &Scene, bundles: &[Arc<LoadedBundle>]) -> Self {
        let organs = bundles
            .iter()
            .enumerate()
            .map(|(i, b)| {
                let mut nodes: Vec<usize> = b.surface.iter().flatten().copied().collect();
                nodes.sort_unstable();
                nodes.dedup();
                let mut local = vec![u32::MAX; b.nodes.len()];
                for (j, &n) in nodes.iter().enumerate() {
                    local[n] = j as u32;
                }
                let v = &b.vademecum;
                let open: Vec<[usize; 3]> = b.surface.iter().copied().filter(|t| t.iter().all(|&n| v.is_loadable(n))).collect();
                OrganSurface {
                    name: scene.spec.organs.get(i).map_or_else(|| format!("organ{i}"), |o| o.name.clone()),
                    positions_m: nodes.iter().flat_map(|&n| b.nodes[n].map(|x| x as f32)).collect(),
                    triangles: b.surface.iter().flatten().map(|&n| local[n]).collect(),
                    accessible: nodes.iter().map(|&n| u8::from(v.is_loadable(n))).collect(),
                    bounds: Bounds::of(&b.nodes, &b.surface),
                    accessible_bounds: (!open.is_empty()).then(|| Bounds::of(&b.nodes, &open)),
                    accessible_triangles: open.len(),
                    nodes,
                }
            })
            .collect();
        Self {
            organs,
            tools: scene.spec.tools.iter().map(|t| t.name().to_string()).collect(),
        }
    }
}

/// One frame: the displacement of every organ's surface at one tick.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// Frame number, from 1, increasing by one per frame produced (0: the rest state).
    pub seq: u64,
    /// The step (pipeline tick) it shows ([`super::Answer::tick`]).
    pub tick: u64,
    /// Session time of that tick (s).
    pub time_s: f64,
    /// Force on the tool (N).
    pub force_n: [f64; 3],
    /// Contact, if any.
    pub contact: Option<Contact>,
    /// Where the tool was at that tick (`None`: no tool state yet, or it was rejected).
    pub tool_m: Option<[f64; 3]>,
    /// Every tool that has moved, in a session that moves named tools (empty otherwise):
    /// the displacements are the field under all of them together.
    pub tools: Vec<ToolFrame>,
    /// Per organ, the displacement (m) of its surface nodes, 3 per node, in
    /// [`OrganSurface::nodes`] order.
    pub displacements_m: Vec<Vec<f32>>,
    /// Per organ, the walls of its cut with their displacements (`None`: not cut).
    pub cuts: Vec<Option<CutFrame>>,
    /// Per organ, its damage (`None`: it does not tear).
    pub damage: Vec<Option<DamageFrame>>,
    /// The visual mesh of a co-rotational cutting organ, split along the cut (`None`: the
    /// session draws the simulation surfaces only).
    pub visual: Option<VisualFrame>,
    /// The surface the blade swept in the cells it entered and has not cut yet, displaced
    /// (co-rotational cutting; `None`: there is none).
    pub partial: Option<PartialFrame>,
}

/// One tool in a frame.
#[derive(Debug, Clone, PartialEq)]
pub struct ToolFrame {
    /// Its name in the scene.
    pub name: String,
    /// Where it was (m; `None`: its state was rejected).
    pub tool_m: Option<[f64; 3]>,
    /// The force on it (N).
    pub force_n: [f64; 3],
    /// Its contact, if any.
    pub contact: Option<Contact>,
}

/// The partial cut of a co-rotational cutting organ in one frame
/// ([`vademecum_engine::pipeline::cutting::PartialCut`]): triangles of three vertices each.
#[derive(Debug, Clone, PartialEq)]
pub struct PartialFrame {
    /// The organ.
    pub organ: usize,
    /// The partial cut's number (changes with its triangles).
    pub seq: u64,
    /// Reference position of every vertex (m), 3 per vertex, 3 vertices per triangle.
    pub positions_m: Arc<[f32]>,
    /// Displacement of every vertex (m), 3 per vertex.
    pub displacements_m: Vec<f32>,
}

/// An organ's visual mesh in one frame (co-rotational cutting, `[organs.visual]`): split
/// along the cut, each vertex following its side of it.
#[derive(Debug, Clone, PartialEq)]
pub struct VisualFrame {
    /// The organ.
    pub organ: usize,
    /// The cut revision the surface was split for (0: uncut); vertices and triangles change
    /// only with it.
    pub revision: u64,
    /// Reference position of every vertex (m), 3 per vertex.
    pub positions_m: Arc<[f32]>,
    /// Triangles, 3 vertex indices each, outward.
    pub triangles: Arc<[u32]>,
    /// Displacement of every vertex (m), 3 per vertex.
    pub displacements_m: Vec<f32>,
}

/// The damage of a tearing organ in one frame (see [`TearPicture`]).
#[derive(Debug, Clone, PartialEq)]
pub struct DamageFrame {
    /// Damage of every mesh cell.
    pub cell_damage: Vec<f32>,
    /// Damage of the cell each surface triangle bounds, in [`OrganSurface::triangles`] order.
    pub triangle_damage: Vec<f32>,
    /// The torn threshold.
    pub torn: f32,
    /// Whether the grasper holds the tissue.
    pub grasped: bool,
    /// Energy dissipated so far (J).
    pub dissipated_j: f64,
}

/// The walls of an organ's cut in one frame ([`CutWalls`](vademecum_engine::xfem::view::CutWalls)):
/// both sides of every opening, each vertex a node on one side.
#[derive(Debug, Clone, PartialEq)]
pub struct CutFrame {
    /// The cut's revision (changes when the cut grows, and with it the walls).
    pub revision: u64,
    /// Reference position of every vertex (m), 3 per vertex.
    pub positions_m: Arc<[f32]>,
    /// Triangles, 3 vertex indices each, facing into the opening.
    pub triangles: Arc<[u32]>,
    /// Per vertex, 0 for its node's own side, 1 for the other side (the copy).
    pub side: Arc<[u8]>,
    /// Displacement of every vertex (m), 3 per vertex.
    pub displacements_m: Vec<f32>,
}

impl Frame {
    /// The undeformed state.
    pub fn rest(g: &SurfaceGeometry) -> Self {
        Self {
            seq: 0,
            tick: 0,
            time_s: 0.0,
            force_n: [0.0; 3],
            contact: None,
            tool_m: None,
            tools: Vec::new(),
            displacements_m: g.organs.iter().map(|o| vec![0.0; 3 * o.nodes.len()]).collect(),
            cuts: vec![None; g.organs.len()],
            damage: vec![None; g.organs.len()],
            visual: None,
            partial: None,
        }
    }
}

/// The geometry of the walls of one revision of a cut (kept between frames).
struct WallGeometry {
    revision: u64,
    positions_m: Arc<[f32]>,
    triangles: Arc<[u32]>,
    side: Arc<[u8]>,
}

impl WallGeometry {
    fn of(p: &CutPicture, nodes: &[[f64; 3]]) -> Self {
        let v = &p.walls.vertices;
        Self {
            revision: p.revision,
            positions_m: v.iter().flat_map(|w| nodes[w.node].map(|x| x as f32)).collect(),
            triangles: p.walls.triangles.iter().flatten().copied().collect(),
            side: v.iter().map(|w| u8::from(w.copy.is_some())).collect(),
        }
    }
}

/// What the frame thread keeps to draw a tearing organ.
pub(super) struct TearView {
    pictures: TearPictures,
    /// The offline data of every grasp site (a picture says whose amplitudes it holds).
    offline: Vec<Arc<TearOffline>>,
    /// The cell each surface triangle bounds.
    triangle_cell: Vec<usize>,
    /// The whole displacement, rebuilt per frame.
    u: Vec<f64>,
}

impl TearView {
    /// The view of `offline`'s organ (one per grasp site, not empty), whose surface is
    /// `surface`.
    pub fn new(pictures: TearPictures, offline: Vec<Arc<TearOffline>>, surface: &OrganSurface) -> Self {
        let mesh = &offline[0].model.mesh;
        let mut cells_of: Vec<Vec<usize>> = vec![Vec::new(); mesh.n_nodes()];
        for c in 0..mesh.n_cells() {
            for &a in mesh.cell(c) {
                cells_of[a].push(c);
            }
        }
        let triangle_cell = surface
            .triangles
            .chunks_exact(3)
            .map(|t| {
                let [a, b, c] = [0, 1, 2].map(|k| surface.nodes[t[k] as usize]);
                cells_of[a]
                    .iter()
                    .copied()
                    .find(|&cell| mesh.cell(cell).contains(&b) && mesh.cell(cell).contains(&c))
                    .unwrap_or(0)
            })
            .collect();
        let u = vec![0.0; 3 * mesh.n_nodes()];
        Self {
            pictures,
            offline,
            triangle_cell,
            u,
        }
    }

    /// Draws the latest picture into `frame`: the organ's surface displacement and damage.
    fn draw(&mut self, nodes: &[usize], frame: &mut Frame) {
        let p: &TearPicture = self.pictures.read();
        let o = p.organ;
        if o >= frame.displacements_m.len() {
            return;
        }
        let Some(off) = self.offline.get(p.site) else { return };
        off.displacement(&p.amplitudes, &mut self.u);
        for (j, &n) in nodes.iter().enumerate() {
            for k in 0..3 {
                frame.displacements_m[o][3 * j + k] += self.u[3 * n + k] as f32;
            }
        }
        frame.damage[o] = Some(DamageFrame {
            triangle_damage: self.triangle_cell.iter().map(|&c| p.cell_damage[c]).collect(),
            cell_damage: p.cell_damage.clone(),
            torn: p.torn,
            grasped: p.grasped,
            dissipated_j: p.dissipated_j,
        });
    }
}

/// The co-rotational deformation the frame thread advances, and the visual geometry of its
/// revision (kept between frames).
struct Corotational {
    deformation: CorotationalDeformation,
    visual: Option<(u64, Arc<[f32]>, Arc<[u32]>)>,
    /// The partial cut's geometry: its number, vertices, their embedding, positions.
    partial: Option<PartialGeometry>,
    scratch: Vec<f64>,
}

/// The partial cut of one number, embedded in the organ.
struct PartialGeometry {
    seq: u64,
    points: Vec<[f64; 3]>,
    embedding: vademecum_engine::xfem::visual::Embedding,
    positions_m: Arc<[f32]>,
}

pub(super) struct FrameProducer {
    corotational: Option<Corotational>,
    bundles: Vec<Arc<LoadedBundle>>,
    cut: Option<Arc<CutStatus>>,
    tear: Option<TearView>,
    walls: Option<WallGeometry>,
    fields: Vec<Arc<NodeMajorField>>,
    /// Per organ, the modes its frames keep while the session runs reduced (0: all; see
    /// [`super::fidelity`]).
    fallback_modes: Vec<usize>,
    geometry: Arc<SurfaceGeometry>,
    latest: triple_buffer::Output<Latest>,
    tx: watch::Sender<Arc<Frame>>,
    stats: Arc<TickStats>,
    stop: Arc<AtomicBool>,
    /// The shortest interval between frames (the session's frame rate).
    interval: Duration,
    /// The rates its viewers ask.
    demand: Arc<FrameDemand>,
    /// The frames made so far.
    seq: u64,
    /// When the next frame is due.
    next: Instant,
    scratch: Scratch,
}

/// A producer's working arrays (kept between frames).
#[derive(Default)]
struct Scratch {
    /// Each organ's vademecum coefficients under the contact.
    coeffs: Vec<Vec<f64>>,
    /// The same in `f32`, for the node-major field.
    c32: Vec<Vec<f32>>,
    /// The cut's enrichment coefficients.
    cut_coeffs: Vec<f64>,
    /// The uncut field at the cut's wall nodes.
    uncut: Vec<f64>,
}

impl FrameProducer {
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        bundles: Vec<Arc<LoadedBundle>>,
        geometry: Arc<SurfaceGeometry>,
        latest: triple_buffer::Output<Latest>,
        tx: watch::Sender<Arc<Frame>>,
        stats: Arc<TickStats>,
        stop: Arc<AtomicBool>,
        rate_hz: f64,
        cut: Option<Arc<CutStatus>>,
        tear: Option<TearView>,
    ) -> Self {
        let fields = bundles
            .iter()
            .zip(&geometry.organs)
            .map(|(b, o)| b.surface_field(&o.nodes))
            .collect();
        let fallback_modes = bundles
            .iter()
            .map(|b| b.modes_for_error(super::fidelity::FALLBACK_FIELD_ERROR).unwrap_or(0))
            .collect();
        let rate = if rate_hz.is_finite() && rate_hz > 0.0 { rate_hz } else { 30.0 };
        let scratch = Scratch {
            coeffs: bundles.iter().map(|b| vec![0.0; b.vademecum.modes()]).collect(),
            c32: bundles.iter().map(|b| vec![0.0; b.vademecum.modes()]).collect(),
            ..Scratch::default()
        };
        Self {
            corotational: None,
            bundles,
            cut,
            tear,
            walls: None,
            fields,
            fallback_modes,
            geometry,
            latest,
            tx,
            stats,
            stop,
            interval: Duration::from_secs_f64(1.0 / rate),
            demand: Arc::default(),
            seq: 0,
            next: Instant::now(),
            scratch,
        }
    }

    /// The same producer making frames at the rate its viewers ask ([`FrameDemand`]), at most
    /// its own.
    pub fn with_demand(mut self, demand: Arc<FrameDemand>) -> Self {
        self.demand = demand;
        self
    }

    /// The same producer drawing the co-rotational `deformation` of a cut organ (advanced
    /// every frame, watched or not; see `pipeline::corotational`).
    pub fn with_corotational(mut self, deformation: CorotationalDeformation) -> Self {
        self.corotational = Some(Corotational {
            deformation,
            visual: None,
            partial: None,
            scratch: Vec::new(),
        });
        self
    }

    /// A turn ([`super::workers`]): the next frame when it is due, made while someone
    /// watches and the tick state changes (a co-rotational deformation advances every frame,
    /// watched or not); when the next one is due.
    pub fn poll(&mut self) -> Poll {
        if self.stop.load(Ordering::Relaxed) {
            return Poll::Ended;
        }
        let now = Instant::now();
        if now < self.next {
            return Poll::At(self.next);
        }
        // a co-rotational deformation advances at the session's rate, watched or not
        let interval = if self.corotational.is_some() {
            self.interval
        } else {
            self.demand.interval(self.interval)
        };
        self.next += interval;
        if self.next < now {
            self.next = now + interval;
        }
        if self.corotational.is_some() {
            self.corotational_turn();
        } else if self.tx.receiver_count() > 0 && self.latest.updated() {
            let mut scratch = std::mem::take(&mut self.scratch);
            let frame = self.frame(&mut scratch);
            self.scratch = scratch;
            self.tx.send_replace(Arc::new(frame));
            self.stats.frames.fetch_add(1, Ordering::Relaxed);
        }
        Poll::At(self.next)
    }

    /// The next frame, made now whether watched or not (a deterministic session's,
    /// [`Lockstep`]); a co-rotational deformation advances one frame.
    fn make_frame(&mut self) -> Arc<Frame> {
        if self.corotational.is_some() {
            let (l, picture) = self.advance_corotational();
            self.seq += 1;
            let seq = self.seq;
            self.stats.frames.fetch_add(1, Ordering::Relaxed);
            return Arc::new(self.corotational_frame(&l, seq, picture.as_deref()));
        }
        let mut scratch = std::mem::take(&mut self.scratch);
        let frame = self.frame(&mut scratch);
        self.scratch = scratch;
        self.stats.frames.fetch_add(1, Ordering::Relaxed);
        Arc::new(frame)
    }

    /// Advances the co-rotational deformation one frame under the latest tick state; returns
    /// that state and the cut picture it took.
    fn advance_corotational(&mut self) -> (Latest, Option<Arc<CutPicture>>) {
        let l = *self.latest.read();
        let picture = self.cut.as_ref().and_then(|s| s.picture());
        let Some(c) = &mut self.corotational else { return (l, picture) };
        // under load the deformation keeps its factor (its cheaper setting)
        c.deformation.set_reduced(self.stats.reduced.load(Ordering::Relaxed));
        let t = Instant::now();
        match c.deformation.step_with_picture(picture.as_deref(), l.state.contact.as_ref()) {
            Ok(outcome) => self.stats.record_corotational(&outcome, t.elapsed()),
            Err(e) => {
                self.stats.corotational_failures.fetch_add(1, Ordering::Relaxed);
                tracing::warn!("a co-rotational frame failed: {e}");
            }
        }
        (l, picture)
    }

    /// Advances the co-rotational deformation one frame and publishes its frame when watched.
    fn corotational_turn(&mut self) {
        if self.corotational.is_none() {
            return;
        }
        let (l, picture) = self.advance_corotational();
        if self.tx.receiver_count() > 0 {
            self.seq += 1;
            let frame = self.corotational_frame(&l, self.seq, picture.as_deref());
            self.tx.send_replace(Arc::new(frame));
            self.stats.frames.fetch_add(1, Ordering::Relaxed);
        }
    }

    /// The frame of the latest tick state: every organ's surface displaced by its
    /// vademecum's field under the contact, with the cut and the damage drawn.
    fn frame(&mut self, s: &mut Scratch) -> Frame {
        let l = *self.latest.read();
        let mut frame = Frame::rest(&self.geometry);
        self.seq += 1;
        frame.seq = self.seq;
        frame.tick = l.tick;
        frame.time_s = l.time_us as f64 * 1e-6;
        frame.force_n = l.state.force_n;
        frame.contact = l.state.contact;
        frame.tool_m = l.state.tool_m;
        frame.tools = self.tool_frames(&l);
        // the deformable tissue's part of each tool's load (the rest goes into the support),
        // superposed per organ: the answered tool's last, so that `s.coeffs` holds its own
        let mut loaded = None;
        let mut touched = vec![false; self.bundles.len()];
        let mut contacts: Vec<(Contact, bool)> = if frame.tools.is_empty() {
            l.state.contact.map(|c| (c, true)).into_iter().collect()
        } else {
            frame
                .tools
                .iter()
                .filter_map(|t| t.contact)
                .map(|c| (c, Some(c) == l.state.contact))
                .collect()
        };
        contacts.sort_by_key(|&(_, own)| own);
        for (c, own) in contacts {
            let v = &self.bundles[c.organ].vademecum;
            if !v.coefficients(c.nodes, c.weights, c.tissue_force_n, &mut s.coeffs[c.organ]) {
                continue;
            }
            let first = !std::mem::replace(&mut touched[c.organ], true);
            for (a, b) in s.c32[c.organ].iter_mut().zip(&s.coeffs[c.organ]) {
                *a = if first { *b as f32 } else { *a + *b as f32 };
            }
            if own {
                loaded = Some(c);
            }
        }
        // under load, the prefix of the modes that meets the fallback's field error
        let reduced = self.stats.reduced.load(Ordering::Relaxed);
        for (o, _) in touched.iter().enumerate().filter(|(_, t)| **t) {
            let prefix = if reduced { self.fallback_modes[o] } else { 0 };
            self.fields[o].eval_prefix(&s.c32[o], prefix, &mut frame.displacements_m[o]);
        }
        if let Some(p) = self.cut.as_ref().and_then(|s| s.picture()) {
            self.draw_cut(&p, loaded, &s.coeffs, &mut s.cut_coeffs, &mut s.uncut, &mut frame);
        }
        if let Some(t) = &mut self.tear {
            let o = t.pictures.peek_output_buffer().organ;
            if let Some(surface) = self.geometry.organs.get(o) {
                t.draw(&surface.nodes, &mut frame);
            }
        }
        frame
    }

    /// Every tool of the latest tick that has moved, with its name (a session that moves
    /// named tools; empty otherwise).
    fn tool_frames(&self, l: &Latest) -> Vec<ToolFrame> {
        l.tools
            .iter()
            .enumerate()
            .filter_map(|(i, t)| {
                let t = t.as_ref()?;
                Some(ToolFrame {
                    name: self.geometry.tools.get(i).cloned().unwrap_or_else(|| format!("tool{i}")),
                    tool_m: t.tool_m,
                    force_n: t.force_n,
                    contact: t.contact,
                })
            })
            .collect()
    }

    /// The frame of a co-rotational cutting session: the deformation's surface, cut walls
    /// (of the picture `p` when it is the model's revision) and visual mesh.
    fn corotational_frame(&mut self, l: &Latest, seq: u64, p: Option<&CutPicture>) -> Frame {
        let mut frame = Frame::rest(&self.geometry);
        frame.seq = seq;
        frame.tick = l.tick;
        frame.time_s = l.time_us as f64 * 1e-6;
        frame.force_n = l.state.force_n;
        frame.contact = l.state.contact;
        frame.tool_m = l.state.tool_m;
        let Some(c) = &mut self.corotational else { return frame };
        let def = &c.deformation;
        let o = def.organ();
        let (Some(surface), Some(enr)) = (self.geometry.organs.get(o), def.enrichment()) else {
            return frame;
        };
        def.node_displacements(&surface.nodes, &mut frame.displacements_m[o]);
        let d = def.d();
        let n = 3 * self.bundles[o].nodes.len();
        if let Some(p) = p.filter(|p| p.organ == o && p.revision == def.revision() && !enr.is_empty()) {
            if self.walls.as_ref().is_none_or(|w| w.revision != p.revision) {
                self.walls = Some(WallGeometry::of(p, &self.bundles[o].nodes));
            }
            if let Some(w) = &self.walls {
                let displacements_m = p
                    .walls
                    .vertices
                    .iter()
                    .flat_map(|v| {
                        (0..3).map(move |i| {
                            let jump = v.copy.map_or(0.0, |(k, s)| s * d.get(n + 3 * k + i).copied().unwrap_or(0.0));
                            (d[3 * v.node + i] + jump) as f32
                        })
                    })
                    .collect();
                frame.cuts[o] = Some(CutFrame {
                    revision: w.revision,
                    positions_m: w.positions_m.clone(),
                    triangles: w.triangles.clone(),
                    side: w.side.clone(),
                    displacements_m,
                });
            }
        }
        if let Some(v) = def.visual() {
            if c.visual.as_ref().is_none_or(|g| g.0 != v.revision) {
                c.visual = Some((
                    v.revision,
                    v.mesh.vertices.iter().flat_map(|p| p.map(|x| x as f32)).collect(),
                    v.mesh.triangles.iter().flat_map(|t| t.map(|i| i as u32)).collect(),
                ));
            }
            def.visual_displacements(&mut c.scratch);
            if let Some((revision, positions_m, triangles)) = &c.visual {
                frame.visual = Some(VisualFrame {
                    organ: o,
                    revision: *revision,
                    positions_m: positions_m.clone(),
                    triangles: triangles.clone(),
                    displacements_m: c.scratch.iter().map(|&x| x as f32).collect(),
                });
            }
        }
        // the partial cut, embedded once per number, displaced every frame
        let part = self.cut.as_ref().map(|s| s.partial()).filter(|p| !p.triangles.is_empty());
        match part {
            None => c.partial = None,
            Some(part) => {
                if c.partial.as_ref().is_none_or(|g| g.seq != part.seq) {
                    let points: Vec<[f64; 3]> = part.triangles.iter().flatten().copied().collect();
                    c.partial = def.embed_points(&points).ok().map(|embedding| PartialGeometry {
                        seq: part.seq,
                        positions_m: points.iter().flat_map(|p| p.map(|x| x as f32)).collect(),
                        points,
                        embedding,
                    });
                }
                if let Some(g) = &c.partial {
                    def.point_displacements(&g.embedding, &g.points, &mut c.scratch);
                    frame.partial = Some(PartialFrame {
                        organ: o,
                        seq: g.seq,
                        positions_m: g.positions_m.clone(),
                        displacements_m: c.scratch.iter().map(|&x| x as f32).collect(),
                    });
                }
            }
        }
        frame
    }

    /// Adds the cut of picture `p` to `frame`: what it moves the organ's surface by, and its
    /// walls, displaced, under the contact `loaded` (the vademecum's coefficients `coeffs`).
    fn draw_cut(
        &mut self,
        p: &CutPicture,
        loaded: Option<Contact>,
        coeffs: &[Vec<f64>],
        cut_coeffs: &mut Vec<f64>,
        uncut: &mut Vec<f64>,
        frame: &mut Frame,
    ) {
        let o = p.organ;
        if o >= self.bundles.len() {
            return;
        }
        if self.walls.as_ref().is_none_or(|w| w.revision != p.revision) {
            self.walls = Some(WallGeometry::of(p, &self.bundles[o].nodes));
        }
        let Some(w) = &self.walls else { return };
        let mut displacements_m = vec![0.0; w.positions_m.len()];
        if let Some(c) = loaded.filter(|c| c.organ == o) {
            uncut.resize(3 * p.wall_nodes.len(), 0.0);
            self.bundles[o].vademecum.field_at(&coeffs[o], &p.wall_nodes, uncut);
            p.response(&c, cut_coeffs);
            p.add_to(cut_coeffs, &self.geometry.organs[o].nodes, &mut frame.displacements_m[o]);
            p.wall_displacements(cut_coeffs, uncut, &mut displacements_m);
        }
        frame.cuts[o] = Some(CutFrame {
            revision: w.revision,
            positions_m: w.positions_m.clone(),
            triangles: w.triangles.clone(),
            side: w.side.clone(),
            displacements_m,
        });
    }
}

/// A session's frame producer on its way to a frame worker (or a thread of its own), and the
/// signal that it has ended.
pub(super) struct FrameJob {
    pub producer: FrameProducer,
    /// Signalled once the producer has been dropped (one slot: never blocks).
    pub done: SyncSender<()>,
}

impl Polled for FrameJob {
    /// A co-rotational deformation (milliseconds per frame, on a thread of its own) yields to
    /// the tick threads.
    fn start(&mut self) {
        if self.producer.corotational.is_some() {
            vademecum_engine::pipeline::lower_thread_priority();
        }
        self.producer.next = Instant::now();
    }

    fn poll(&mut self) -> Poll {
        self.producer.poll()
    }
}

impl Placed for FrameJob {
    fn end(self) {
        drop(self.producer);
        let _ = self.done.try_send(());
    }
}

/// How the frame workers run.
#[derive(Debug, Clone, Copy)]
pub struct FrameWorkersConfig {
    /// Worker threads (at least 1).
    pub workers: usize,
}

impl Default for FrameWorkersConfig {
    /// One worker per CPU the process may use.
    fn default() -> Self {
        Self {
            workers: std::thread::available_parallelism().map_or(1, |n| n.get()),
        }
    }
}

/// A pool of frame workers: a few threads that each make the frames of many sessions (a
/// session's frames cost about a millisecond at 30 Hz on the liver — one thread sleeping per
/// session would cost a thread and its wake-ups each). A co-rotational session's producer runs
/// on a thread of its own at a lowered priority (its deformation costs milliseconds per frame,
/// and would delay the other sessions' frames).
#[derive(Debug)]
pub struct FrameWorkers {
    pool: Pool<FrameJob>,
}

impl FrameWorkers {
    /// Starts `config.workers` workers at normal priority.
    pub fn new(config: FrameWorkersConfig) -> std::io::Result<Self> {
        let pool = Pool::new("frame-worker", PoolConfig::plain(config.workers))?;
        Ok(Self { pool })
    }

    /// Sessions on each worker.
    pub fn load(&self) -> Vec<usize> {
        self.pool.load()
    }

    /// Each worker's measured utilisation (CPU time over wall time, last quarter second).
    pub fn utilisation(&self) -> Vec<f64> {
        self.pool.utilisation()
    }

    /// Hands `job` to the least-loaded worker; returns the thread to unpark when the session
    /// stops.
    pub(super) fn place(&self, job: FrameJob) -> Result<Thread, PlaceError> {
        self.pool.place(job, None)
    }
}

/// Frames a deterministic session keeps for its recorder, at most (the producer, and with it
/// the tick, waits for a recorder that falls this far behind: no frame is lost).
pub const FRAME_LOG: usize = 256;

/// Runs the frame producer of a deterministic session on this thread: a frame per request of
/// the tick thread ([`Lockstep`]), published to viewers and sent, every one, to `log` (the
/// recorder's), then reported made. Ends when stopped or when the tick's end is dropped.
fn run_lockstep(mut job: FrameJob, requests: std::sync::mpsc::Receiver<()>, made: SyncSender<()>, log: SyncSender<Arc<Frame>>) {
    job.start();
    loop {
        match requests.recv_timeout(Duration::from_millis(20)) {
            Ok(()) => {
                let frame = job.producer.make_frame();
                job.producer.tx.send_replace(frame.clone());
                // the recorder may have gone (the run failed): frames are then only published
                let _ = log.send(frame);
                if made.send(()).is_err() {
                    break;
                }
            }
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {}
            Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => break,
        }
        if job.producer.stop.load(Ordering::Relaxed) {
            break;
        }
    }
    job.end();
}

/// Starts the frame thread of a deterministic session: returns the thread, the tick's end of
/// its frames and the recorder's log of every frame ([`FRAME_LOG`] frames deep).
pub(super) fn spawn_lockstep(
    id: &str,
    job: FrameJob,
    rate_hz: f64,
    period: Duration,
) -> (std::thread::JoinHandle<()>, Lockstep, std::sync::mpsc::Receiver<Arc<Frame>>) {
    let (requests, requests_rx) = std::sync::mpsc::sync_channel(1);
    let (made_tx, made) = std::sync::mpsc::sync_channel(1);
    let (log, log_rx) = std::sync::mpsc::sync_channel(FRAME_LOG);
    let t = std::thread::Builder::new()
        .name(format!("frames-{id}"))
        .spawn(move || run_lockstep(job, requests_rx, made_tx, log))
        .expect("the OS can start a thread");
    let rate = if rate_hz.is_finite() && rate_hz > 0.0 { rate_hz } else { 30.0 };
    let lockstep = Lockstep::new(1.0 / (rate * period.as_secs_f64()), requests, made);
    (t, lockstep, log_rx)
}
