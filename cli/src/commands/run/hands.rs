//! The hands a headless run plays: one trajectory for the session's one tool at a time, or one
//! per named tool of the scene — `--script TOOL=CSV`, repeated, or, for a scene that composes
//! effects on different organs, the built-in incisions in the scalpel's hand, the built-in
//! grasp in the grasper's and the built-in palpation of the organ that deforms largely in the
//! probe's, at once.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::bail;
use vademecum_engine::bundle::LoadedBundle;
use vademecum_engine::scene::Scene;
use vademecum_engine::scene::schema::ToolSpec;
use vademecum_server::session::Trajectory;

/// A hand the run plays.
pub(super) struct PlayedHand {
    /// The scene tool it moves (`None`: the session's one tool at a time).
    pub tool: Option<usize>,
    /// The tool's name (empty for the one tool at a time).
    pub name: String,
    pub trajectory: Trajectory,
    /// Where the trajectory came from, for the summary.
    pub source: String,
}

/// What a hand moves, as the force log needs it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum HandKind {
    Probe,
    Scalpel,
    Grasper,
}

impl PlayedHand {
    /// What the hand moves in a session that cuts (`cutting`) and tears (`tearing`): its
    /// named tool's kind; the one tool at a time is the scalpel when the session cuts, the
    /// grasper when it only tears, else the probe.
    pub fn kind(&self, scene: &Scene, cutting: bool, tearing: bool) -> HandKind {
        match self.tool.map(|t| &scene.spec.tools[t]) {
            Some(ToolSpec::Scalpel { .. }) => HandKind::Scalpel,
            Some(ToolSpec::Grasper { .. }) => HandKind::Grasper,
            Some(ToolSpec::Probe { .. }) => HandKind::Probe,
            None if cutting => HandKind::Scalpel,
            None if tearing => HandKind::Grasper,
            None => HandKind::Probe,
        }
    }

    /// Where the run writes this hand's trajectory: `trajectory.csv` for a run of one hand,
    /// `trajectory_<tool>.csv` for each of several.
    pub fn script_file(&self, record: &Path, several: bool) -> PathBuf {
        if several {
            record.join(format!("trajectory_{}.csv", self.name))
        } else {
            record.join("trajectory.csv")
        }
    }
}

/// The hands of `--script` arguments: `CSV` (the one tool at a time) or `TOOL=CSV` (the
/// scene's tool of that name); several need a tool each, a tool takes one. Every file is
/// read (and a bad one refused) before anything is built.
pub(super) fn scripted(scene: &Scene, scripts: &[String]) -> anyhow::Result<Vec<PlayedHand>> {
    let tools = &scene.spec.tools;
    let mut hands: Vec<PlayedHand> = Vec::with_capacity(scripts.len());
    for arg in scripts {
        let named = arg
            .split_once('=')
            .and_then(|(name, path)| tools.iter().position(|t| t.name() == name).map(|i| (i, path)));
        let (tool, path) = match named {
            Some((i, path)) => (Some(i), PathBuf::from(path)),
            None => (None, PathBuf::from(arg)),
        };
        if scripts.len() > 1 && tool.is_none() {
            bail!(
                "--script {arg}: with several scripts each names its tool as TOOL=CSV (the scene's tools: {})",
                tools.iter().map(|t| format!("'{}'", t.name())).collect::<Vec<_>>().join(", ")
            );
        }
        if let Some(i) = tool
            && hands.iter().any(|h| h.tool == Some(i))
        {
            bail!("--script {arg}: tool '{}' already has a script", tools[i].name());
        }
        let trajectory = Trajectory::read(&path)?;
        if let Some(i) = tool
            && matches!(tools[i], ToolSpec::Scalpel { .. })
            && !trajectory.has_blade()
        {
            bail!(
                "--script {arg}: '{}' is a scalpel, but the trajectory has no blade: add the columns bx_m,by_m,bz_m,qw,qx,qy,qz (see `vademecum run --help`)",
                tools[i].name()
            );
        }
        hands.push(PlayedHand {
            tool,
            name: tool.map_or(String::new(), |i| tools[i].name().to_string()),
            trajectory,
            source: path.display().to_string(),
        });
    }
    Ok(hands)
}

/// The built-in hands of a scene without a script: for a scene that composes effects on
/// different organs, one hand per effect at once — the scalpel's incisions (cutting), the
/// grasper's grasp (tearing), the probe's palpation of the first organ that deforms largely —
/// when there are two or more; otherwise the one built-in trajectory of
/// [`super::builtin_trajectory`].
pub(super) fn builtin(scene: &Scene, bundles: &[Arc<LoadedBundle>], radius: f64, depth: Option<f64>) -> anyhow::Result<Vec<PlayedHand>> {
    let tools = &scene.spec.tools;
    let fx = &scene.spec.effects;
    let scalpel = tools
        .iter()
        .position(|t| matches!(t, ToolSpec::Scalpel { .. }))
        .filter(|_| fx.cutting);
    let grasper = tools
        .iter()
        .position(|t| matches!(t, ToolSpec::Grasper { .. }))
        .filter(|_| fx.tearing);
    let probe = tools.iter().enumerate().find_map(|(i, t)| match t {
        ToolSpec::Probe { radius, .. } => Some((i, *radius)),
        _ => None,
    });
    let large = (0..scene.spec.organs.len()).find(|&i| scene.organ_large(i));
    let pressing = probe.zip(large).filter(|_| scalpel.is_some() || grasper.is_some());
    if usize::from(scalpel.is_some()) + usize::from(grasper.is_some()) + usize::from(pressing.is_some()) < 2 {
        let (trajectory, source) = super::builtin_trajectory(scene, bundles, radius, depth)?;
        return Ok(vec![PlayedHand {
            tool: None,
            name: String::new(),
            trajectory,
            source,
        }]);
    }
    let hand = |tool: usize, (trajectory, source): (Trajectory, String)| PlayedHand {
        tool: Some(tool),
        name: tools[tool].name().to_string(),
        trajectory,
        source,
    };
    let mut hands = Vec::new();
    if let Some(s) = scalpel {
        hands.push(hand(s, super::builtin_incisions(scene, bundles)?));
    }
    if let Some(g) = grasper {
        hands.push(hand(g, super::builtin_grasp(scene)?));
    }
    if let Some(((p, r), organ)) = pressing {
        hands.push(hand(p, super::builtin_palpation(scene, bundles, organ, r, depth)?));
    }
    Ok(hands)
}

/// The run's length (s): its longest hand's.
pub(super) fn duration_s(hands: &[PlayedHand]) -> f64 {
    hands.iter().map(|h| h.trajectory.duration_s()).fold(0.0, f64::max)
}
