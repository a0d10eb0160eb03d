//! Ray counts of a render, by kind, and the work that skipping saved.

use std::ops::AddAssign;

#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RayStats {
    /// Camera (primary) rays.
    pub camera: u64,
    /// Mirrored rays traced.
    pub reflected: u64,
    /// Shadow rays traced against candidate occluders.
    pub shadow: u64,
    /// Light points behind the surface: blocked by the surface itself.
    pub shadow_backfacing: u64,
    /// Shadow rays not traced: no object could block them.
    pub shadow_unoccluded: u64,
    /// Shadow rays not traced: one occluder hides the whole light.
    pub shadow_umbra: u64,
    /// Shadow rays not traced: shadows are switched off.
    pub shadow_disabled: u64,
    /// Shadow rays not traced: neither diffuse nor specular needs them.
    pub shadow_unneeded: u64,
    /// Shadow rays not traced: the adaptive mode's probes all agreed
    /// (an approximation, unlike the other skips).
    pub shadow_adaptive: u64,
    /// Reflected rays not traced: the path weight fell below 1/1024.
    pub reflected_culled: u64,
}

impl RayStats {
    /// Rays actually traced.
    pub fn traced(&self) -> u64 {
        self.camera + self.reflected + self.shadow
    }

    /// Shadow rays whose answer was found without tracing them.
    pub fn shadow_skipped(&self) -> u64 {
        self.shadow_unoccluded + self.shadow_umbra + self.shadow_unneeded + self.shadow_adaptive
    }

    /// Traced rays plus the shadow rays the skipping answered: what a
    /// tracer without skipping would have traced.
    pub fn effective(&self) -> u64 {
        self.traced() + self.shadow_skipped()
    }
}

impl AddAssign for RayStats {
    fn add_assign(&mut self, o: RayStats) {
        self.camera += o.camera;
        self.reflected += o.reflected;
        self.shadow += o.shadow;
        self.shadow_backfacing += o.shadow_backfacing;
        self.shadow_unoccluded += o.shadow_unoccluded;
        self.shadow_umbra += o.shadow_umbra;
        self.shadow_disabled += o.shadow_disabled;
        self.shadow_unneeded += o.shadow_unneeded;
        self.shadow_adaptive += o.shadow_adaptive;
        self.reflected_culled += o.reflected_culled;
    }
}
