//! Which part of the light transport a camera path belongs to, decided vertex by vertex:
//! whether its view bent at glass before it met anything opaque, and whether it is a path the
//! caustic light tracer (`light_tracing.rs`) or photon merging (`photon_merging.rs`) carries
//! instead of the path tracer. The path filters of the analysis tools read the same classes.

/// Which of the paths an image counts. The two parts add up to the whole image, sample by
/// sample (tested), so rendering each says where an estimator's noise comes from (the
/// `trace_convergence` example's `--paths`). Not an estimator: an image of a part is not the
/// scene's.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PathFilter {
    #[default]
    All,
    /// Paths whose view from the camera bends at glass (a reflection, or a refraction through
    /// solid or rough glass) before meeting anything opaque: what the camera sees in or
    /// through bending glass. No connection to the camera can reach these, so the light
    /// tracer cannot help with them; caustics seen this way are specular-diffuse-specular
    /// paths, which no unbiased estimator here samples well.
    BentView,
    /// The rest: paths that reach their first opaque surface (or a light, or the background)
    /// in a straight line, straight crossings of smooth thin panes included. Every light
    /// tracer path is one.
    StraightView,
}

impl PathFilter {
    pub fn name(self) -> &'static str {
        match self {
            PathFilter::All => "all",
            PathFilter::BentView => "bent-view",
            PathFilter::StraightView => "straight-view",
        }
    }

    pub fn parse(name: &str) -> Option<Self> {
        [PathFilter::All, PathFilter::BentView, PathFilter::StraightView].into_iter().find(|f| f.name() == name)
    }

    pub(crate) fn counts(self, view_bent: bool) -> bool {
        match self {
            PathFilter::All => true,
            PathFilter::BentView => view_bent,
            PathFilter::StraightView => !view_bent,
        }
    }
}

/// Where a path traced from the camera stands with respect to the light tracer's share.
/// Updated vertex by vertex; [`PathClass::light_traced`] says whether a path ending in a
/// light here belongs to the light tracer (and so is left out of the path tracer).
#[derive(Clone, Copy, Debug, Default)]
pub struct PathClass {
    /// The first vertex that is not a straight pane crossing has been met.
    prefix_decided: bool,
    /// ... and it was opaque: a light path can connect to the camera there.
    connectable: bool,
    /// An opaque vertex has been met since the camera.
    seen_opaque: bool,
    /// A glass vertex other than a straight pane crossing follows the last opaque vertex.
    bent_since_opaque: bool,
    /// Opaque vertices met since the camera (counted up to 2).
    opaque_vertices: u8,
}

impl PathClass {
    /// Record a vertex before its next-event estimation: `glass` is whether its material has
    /// a transmissive dielectric lobe ([`Bsdf::is_glass`]).
    pub fn enter_vertex(&mut self, glass: bool) {
        if glass {
            return;
        }
        if !self.prefix_decided {
            self.prefix_decided = true;
            self.connectable = true;
        }
        self.seen_opaque = true;
        self.bent_since_opaque = false;
        self.opaque_vertices = (self.opaque_vertices + 1).min(2);
    }

    /// Record the event sampled at the vertex last entered.
    pub fn leave_vertex(&mut self, glass: bool, straight_pane_crossing: bool) {
        if glass && !straight_pane_crossing {
            self.bent_since_opaque = true;
            if !self.prefix_decided {
                self.prefix_decided = true;
                self.connectable = false;
            }
        }
    }

    /// Whether the path traced so far, ended by the emitter it just hit, is the light
    /// tracer's.
    pub fn light_traced(&self) -> bool {
        self.connectable && self.seen_opaque && self.bent_since_opaque
    }

    /// Whether a shadow ray from the current vertex (through straight pane crossings only)
    /// makes a path that is the light tracer's: the vertex is glass, so it bends.
    pub fn light_traced_by_shadow_ray(&self, glass: bool) -> bool {
        glass && self.connectable && self.seen_opaque
    }

    /// Whether an opaque vertex has been met since the camera.
    pub fn seen_opaque(&self) -> bool {
        self.seen_opaque
    }

    /// Whether a vertex about to be entered (`glass`: see [`PathClass::enter_vertex`]) is the
    /// first opaque one of a path whose view bent at glass: where photon merging
    /// (`photon_merging.rs`) estimates the light that reached it through bending glass.
    pub fn first_opaque_of_bent_view(&self, glass: bool) -> bool {
        !glass && self.prefix_decided && !self.connectable && !self.seen_opaque
    }

    /// Whether the vertex just entered is the first opaque one of a path that the camera saw
    /// straight (through panes at most).
    pub fn at_first_opaque_of_straight_view(&self) -> bool {
        self.straight_to_one_opaque()
    }

    /// Whether a vertex about to be entered is the second opaque one of a path that the
    /// camera saw straight (through panes at most) and that went straight (through panes
    /// at most) from its first opaque vertex: where photon merging may gather the light that
    /// scattered since the light (a final gather).
    pub fn second_opaque_of_straight_view(&self, glass: bool) -> bool {
        !glass && self.straight_to_one_opaque()
    }

    /// The camera saw one opaque vertex straight, and nothing has bent the path since.
    fn straight_to_one_opaque(&self) -> bool {
        self.connectable && self.opaque_vertices == 1 && !self.bent_since_opaque
    }

    /// [`PathClass::light_traced`]'s mirror for paths whose view bent: whether the path,
    /// ended by the emitter it just hit, is one that photon merging takes.
    pub fn merged(&self) -> bool {
        self.prefix_decided && !self.connectable && self.seen_opaque && self.bent_since_opaque
    }

    /// [`PathClass::light_traced_by_shadow_ray`]'s mirror for paths whose view bent.
    pub fn merged_by_shadow_ray(&self, glass: bool) -> bool {
        glass && self.prefix_decided && !self.connectable && self.seen_opaque
    }

    /// Whether the camera's view bent at glass (a reflection, a refraction through solid or
    /// rough glass) before the path met anything opaque: such paths cannot be the light
    /// tracer's. For next-event estimation at the current vertex pass `Some(glass)`: a shadow
    /// ray leaving a glass vertex that decides the view bends there too.
    pub fn view_bent(&self, shadow_ray_from_glass: Option<bool>) -> bool {
        if self.prefix_decided {
            !self.connectable
        } else {
            shadow_ray_from_glass == Some(true)
        }
    }
}
