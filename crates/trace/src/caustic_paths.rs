//! The caustic estimator's camera paths: the path tracer without the paths its light tracer
//! carries (light that reached an opaque surface through bending glass, `light_tracing.rs`),
//! and, with photon merging, without those its photons carry (`photon_merging.rs`). Which
//! paths those are is read off the path's class (`path_class.rs`) at the emitters a path hits
//! and at the shadow rays it casts; both halves stay unbiased because each path is counted by
//! exactly one of them.

use glam::Vec3;

use crate::bsdf::BsdfSample;
use crate::integrator::{PathHooks, PathScratch, Vertex};
use crate::path_class::PathClass;
use crate::photon_merging::MergingPath;
use crate::prepared::PathSettings;
use crate::rng::Pcg32;

/// The caustic estimator's [`PathHooks`].
#[derive(Clone, Copy)]
pub(crate) struct CausticPaths<'a> {
    /// Photon merging's state for the path, when it runs.
    pub merging: Option<MergingPath<'a>>,
}

impl PathHooks for CausticPaths<'_> {
    fn counts_emitter_hit(&self, class: &PathClass) -> bool {
        !class.light_traced() && !self.merging.is_some_and(|merging| merging.takes_emitter_hit(class))
    }

    fn at_surface(&mut self, vertex: &Vertex, settings: &PathSettings, rng: &mut Pcg32, scratch: &mut PathScratch) -> Option<Vec3> {
        match &mut self.merging {
            Some(merging) => merging.at_surface(vertex, settings, rng, scratch),
            None => Some(Vec3::ZERO),
        }
    }

    fn traces_shadow_ray(&self, vertex: &Vertex) -> bool {
        !vertex.class.light_traced_by_shadow_ray(vertex.glass) && self.merging.is_none_or(|merging| merging.traces_shadow_ray(vertex))
    }

    fn continues(&mut self, vertex: &Vertex, sample: &BsdfSample) -> bool {
        self.merging.as_mut().is_none_or(|merging| merging.continues(vertex, sample))
    }

    fn shadow_rays_follow_glass(&self, vertex: &Vertex) -> bool {
        // The light tracer carries what reaches a surface the camera saw straight through
        // bending glass; so only a surface it cannot connect to gains, and without photons.
        let mut class = vertex.class;
        class.leave_vertex(vertex.glass, false);
        class.leave_vertex(true, false);
        self.merging.is_none() && self.counts_emitter_hit(&class)
    }

    fn takes_reflected_emission(&self) -> bool {
        true
    }
}
