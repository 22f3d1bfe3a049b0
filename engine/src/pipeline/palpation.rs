//! Palpation with a linear PGD vademecum (seed 000 ch. 2): a spherical tip pressing on the
//! accessible surface of each organ.
//!
//! Each tick: the contact of the tip with every organ's accessible surface
//! ([`SurfaceContact`], the deepest one wins), the compliance `C(s)` at the contact point
//! (exact local 3×3 blocks interpolated over the triangle), the force on the tissue
//! `f = C(s)⁻¹δ` for the imposed surface displacement δ, and its reaction `−f` on the tool.
//! No contact, a point the vademecum cannot load, or a singular compliance give zero force.
//!
//! With large deformations (`effects.deformation = "large"`), the force is then scaled by the
//! organ's ANM-POD lattice ([`crate::rom::palpation`]): the ratio of the nonlinear to the linear
//! force at this depth, blended over the four nearest lattice positions — `O(r · order)` per
//! position, no allocation.

use std::sync::Arc;

use super::{Contact, Effect, Events, TickState, ToolInput};
use crate::pgd::Vademecum;
use crate::pgd::contact::SurfaceContact;
use crate::pgd::offline::LoadedBundle;

/// The linear-deformation effect over one vademecum per organ.
#[derive(Debug, Clone)]
pub struct Palpation {
    organs: Vec<(Arc<LoadedBundle>, SurfaceContact)>,
    radius_m: f64,
    large: bool,
    scratch: Vec<f64>,
}

/// Lattice positions blended per evaluation (seed 001 §6.1 interpolates among four).
const NEIGHBOURS: usize = 4;

impl Palpation {
    /// Prepares the contact surfaces of `bundles` for a tip of radius `radius_m` (m); with
    /// `large`, every bundle must carry a large-deformation lattice (checked by the pipeline).
    pub fn new(bundles: Vec<Arc<LoadedBundle>>, radius_m: f64, large: bool) -> Self {
        let scratch = vec![
            0.0;
            bundles
                .iter()
                .filter_map(|b| b.anm.as_ref())
                .map(|l| l.max_modes())
                .max()
                .unwrap_or(0)
        ];
        let organs = bundles
            .into_iter()
            .map(|b| {
                let s = SurfaceContact::new(&b.nodes, &b.surface, &b.vademecum);
                (b, s)
            })
            .collect();
        Self {
            organs,
            radius_m,
            large,
            scratch,
        }
    }
}

impl Effect for Palpation {
    fn name(&self) -> &'static str {
        "palpation"
    }

    fn tick(&mut self, tool: &ToolInput, state: &mut TickState) {
        let mut best: Option<(usize, crate::pgd::contact::ContactPoint)> = None;
        for (i, (_, surface)) in self.organs.iter().enumerate() {
            if let Some(cp) = surface.query(tool.position_m, self.radius_m)
                && best.is_none_or(|(_, b)| cp.depth > b.depth)
            {
                best = Some((i, cp));
            }
        }
        let Some((organ, cp)) = best else {
            return;
        };
        let v = &self.organs[organ].0.vademecum;
        let Some(c) = v.compliance(cp.nodes, cp.weights) else {
            return;
        };
        let mut f = Vademecum::contact_force(&c, cp.penetration);
        if f == [0.0; 3] {
            return;
        }
        // the contact point on the reference surface
        let nodes = &self.organs[organ].0.nodes;
        let mut point = [0.0; 3];
        for (a, &w) in cp.nodes.iter().zip(&cp.weights) {
            for k in 0..3 {
                point[k] += w * nodes[*a][k];
            }
        }
        if self.large
            && let Some(lattice) = &self.organs[organ].0.anm
        {
            let s = lattice.stiffness_ratio(point, cp.depth, NEIGHBOURS, &mut self.scratch);
            f = f.map(|x| x * s.ratio);
        }
        state.force_n = [state.force_n[0] - f[0], state.force_n[1] - f[1], state.force_n[2] - f[2]];
        state.contact = Some(Contact {
            organ,
            nodes: cp.nodes,
            weights: cp.weights,
            point_m: point,
            depth_m: cp.depth,
        });
        state.events.0 |= Events::CONTACT;
    }
}
