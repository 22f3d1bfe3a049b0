//! Haptic contact of a spherical tool tip with an organ's surface, tracked by a proxy that
//! never lets go while the tool is inside.
//!
//! # The proxy (god-object)
//! The device's tip centre c (radius r) may go anywhere, but the point where it acts on the
//! organ — the proxy, a point s on the reference surface — stays on the surface and slides on
//! it (Zilles and Salisbury 1995, "A constraint-based god-object method for haptic display").
//! Each tick the proxy moves from where it was to the surface point s whose smooth outward
//! normal n(s) passes through c — the projection of c along the normal field (angle-weighted
//! vertex pseudo-normals interpolated over each triangle), found by Newton's method in the
//! proxy's triangle and a walk across edges ([`Surface::project`]), never a search from
//! scratch. So a tip deep inside the organ keeps the surface it entered through instead of
//! finding the far side or nothing. The signed distance is `d = |c − s|` along n(s) (negative
//! inside) and the penetration depth `r − d`; both are continuous along any path of c,
//! because the normal field is — the nearest surface point would not be: it jumps across the
//! bisector of every ridge between two triangles once the tip is deeper than the ridge is
//! wide.
//!
//! # Touch and release
//! - *Free*, the tip touches when the nearest surface point is closer than r along the normal:
//!   found by a grid search within r when the tip's grid cell is outside the organ, by a
//!   widening search when it is on the boundary or inside — so a tool that starts inside (a
//!   client that jumps there, a session started with the tool in the tissue) gets the force of
//!   the nearest surface at once.
//! - *In contact*, it stays in contact until the tip's sphere leaves the surface (`d ≥ r`),
//!   however deep it goes, as long as the tip's centre is inside the organ.
//! - *Outside*, a tip whose centre has left the organ — through any part of its surface, by a
//!   press through a thin part or a jump from deep inside — is touched only by the surface its
//!   sphere reaches: when the proxy's branch still says inside (`d < 0`) while the closed
//!   surface says outside ([`Surface::contains`]), the proxy starts again from the nearest
//!   surface point within r, as from free; `d` is never less than the gap to the nearest
//!   triangle; and with no triangle within r the contact is released. So a tool outside the
//!   organ never feels more than `r − gap` of depth, and nothing once clear of it.
//!
//! The surface is the organ's whole boundary, accessible or not: what force each part gives is
//! the effect's business (the palpation effect renders the parts the vademecum cannot load as
//! the rigid support they are attached to).

mod grid;
mod surface;

pub use grid::CellClass;
pub use surface::{Surface, SurfacePoint};

use crate::geometry::vec3::{norm, sub};

/// Most walk steps per tick. A step moves to a neighbouring triangle; at the tick rate a tool
/// moving at 1 m/s crosses about one 1 mm triangle per tick, so 256 steps is a bound against a
/// client that jumps across the organ, never reached by a device.
pub const MAX_WALK_STEPS: usize = 256;

/// The contact of the tip with the surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Touch {
    /// Where the proxy is.
    pub at: SurfacePoint,
    /// The triangle's nodes.
    pub nodes: [usize; 3],
    /// The smooth outward normal at the proxy.
    pub normal: [f64; 3],
    /// Penetration depth `r − d` (m, positive).
    pub depth: f64,
}

impl Touch {
    /// The imposed surface displacement δ = −depth · n (m), inward.
    pub fn penetration(&self) -> [f64; 3] {
        self.normal.map(|n| -self.depth * n)
    }
}

/// The contact state carried from tick to tick: where the proxy is, if in contact.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Proxy {
    /// The proxy's point and its signed distance from the tip last tick.
    last: Option<(SurfacePoint, f64)>,
    /// The tip and radius of the last update: the same again changes nothing (a session that
    /// ticks one tool state several times answers it as a client replaying it once would).
    input: Option<([f64; 3], f64)>,
}

/// The box of a surface's nodes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bounds {
    /// Lower corner (m).
    pub min: [f64; 3],
    /// Upper corner (m).
    pub max: [f64; 3],
}

impl Bounds {
    /// The box of the nodes of `tris`.
    pub fn of(nodes: &[[f64; 3]], tris: &[[usize; 3]]) -> Self {
        let mut b = Bounds {
            min: [f64::INFINITY; 3],
            max: [f64::NEG_INFINITY; 3],
        };
        for &n in tris.iter().flatten() {
            for k in 0..3 {
                b.min[k] = b.min[k].min(nodes[n][k]);
                b.max[k] = b.max[k].max(nodes[n][k]);
            }
        }
        b
    }

    /// Whether `p` lies in the box grown by `margin`.
    pub fn contains(&self, p: [f64; 3], margin: f64) -> bool {
        (0..3).all(|k| p[k] >= self.min[k] - margin && p[k] <= self.max[k] + margin)
    }
}

impl Proxy {
    /// Whether the proxy is in contact.
    pub fn in_contact(&self) -> bool {
        self.last.is_some()
    }

    /// Lets go (a new session, a tool change).
    pub fn release(&mut self) {
        self.last = None;
        self.input = None;
    }

    /// The touch of a tip whose centre is outside the organ: the surface point nearest to it
    /// within `radius`, carried along the normal field to where its normal passes through the
    /// tip (kept at the nearest point where that projection says inside: from outside, only
    /// the surface the sphere reaches may hold the proxy). `None` when no triangle is within
    /// `radius`.
    fn touch_near(surface: &Surface, tip: [f64; 3], radius: f64) -> Option<(SurfacePoint, f64)> {
        let near = surface.nearest_within(tip, radius)?;
        let gap = norm(sub(tip, near.point));
        let d = surface.signed_distance(&near, tip);
        match surface.project((near, d), tip, MAX_WALK_STEPS) {
            // never deeper than the gap to the nearest triangle allows
            Some((at, dp)) if dp >= 0.0 => Some((at, dp.max(gap))),
            Some(found) if d < 0.0 => Some(found),
            _ => Some((near, if d >= 0.0 { gap } else { d })),
        }
    }

    /// Moves the proxy for a tip of radius `radius` at `tip` (see the module docs) and
    /// returns the contact, if any. The same tip and radius as the last update give the same
    /// contact, bit for bit (Newton's method restarted from its own solution would move the
    /// last bits). Allocates nothing.
    pub fn update(&mut self, surface: &Surface, bounds: &Bounds, tip: [f64; 3], radius: f64) -> Option<Touch> {
        if self.input == Some((tip, radius)) {
            return self.last.map(|(at, d)| Self::touch(surface, at, d, radius));
        }
        self.input = Some((tip, radius));
        self.follow(surface, bounds, tip, radius)
    }

    /// The contact of a proxy at `at`, `d` from a tip of radius `radius`.
    fn touch(surface: &Surface, at: SurfacePoint, d: f64, radius: f64) -> Touch {
        Touch {
            at,
            nodes: surface.triangles()[at.triangle],
            normal: surface.normal_at(&at),
            depth: radius - d,
        }
    }

    /// [`Proxy::update`] for a new tip or radius.
    fn follow(&mut self, surface: &Surface, bounds: &Bounds, tip: [f64; 3], radius: f64) -> Option<Touch> {
        if !(tip.iter().all(|x| x.is_finite()) && radius.is_finite() && radius > 0.0) || surface.is_empty() || !bounds.contains(tip, radius)
        {
            self.last = None;
            return None;
        }
        let (at, d) = match self.last {
            // follow the branch; where it ends, the proxy stays where it was and the depth is
            // measured along its normal there (continuous, until the tip comes back)
            Some(last) => {
                let (at, d) = surface.project(last, tip, MAX_WALK_STEPS).unwrap_or_else(|| {
                    let d = surface.signed_distance(&last.0, tip);
                    (last.0, d)
                });
                if d < 0.0 && !surface.contains(tip) {
                    // the branch says inside but the tip is out: it left the organ through
                    // another part of the surface than the proxy's (a press through a thin
                    // part, a jump). Outside, only the surface the sphere reaches may touch it
                    match Self::touch_near(surface, tip, radius) {
                        Some(near) => near,
                        None => {
                            self.last = None;
                            return None;
                        }
                    }
                } else if d >= 0.0 {
                    // the branch says outside: the tip touches no more than the surface it
                    // reaches, r minus its distance to the nearest triangle (the measure along
                    // the proxy's normal can say more where the proxy rests on an edge or where
                    // Newton's method ended: it measures off the normal); nothing when no
                    // triangle is within r. Both bounds are continuous in the tip.
                    match surface.nearest_within(tip, radius) {
                        Some(near) => (at, d.max(norm(sub(tip, near.point)))),
                        None if !surface.contains(tip) => {
                            self.last = None;
                            return None;
                        }
                        None => (at, d),
                    }
                } else {
                    (at, d)
                }
            }
            None => {
                let found = match surface.grid_class(tip) {
                    CellClass::Outside => Self::touch_near(surface, tip, radius),
                    CellClass::Boundary | CellClass::Inside => surface.nearest(tip).map(|near| {
                        let d = surface.signed_distance(&near, tip);
                        surface.project((near, d), tip, MAX_WALK_STEPS).unwrap_or((near, d))
                    }),
                };
                found?
            }
        };
        if d.is_nan() || d >= radius {
            self.last = None;
            return None;
        }
        self.last = Some((at, d));
        Some(Self::touch(surface, at, d, radius))
    }
}

#[cfg(test)]
mod tests;
