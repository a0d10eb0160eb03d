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
    /// `exact` model: hit points whose visible light was computed exactly.
    pub exact_hits: u64,
    /// `exact` model: hit points that fell back to the `analytic` estimate
    /// (see `exact/visible.rs`).
    pub exact_fallbacks: u64,
}

/// One kind of work that skipping answered or saved, for reports.
pub struct Saving {
    /// CSV column name.
    pub key: &'static str,
    /// Table heading (at most 7 characters).
    pub short: &'static str,
    /// What it counts, for a sentence.
    pub label: &'static str,
    pub count: fn(&RayStats) -> u64,
}

/// Every kind of skipped work, in report order.
pub const SAVINGS: [Saving; 5] = [
    Saving {
        key: "shadow_backfacing",
        short: "backfac",
        label: "shadow rays behind the surface (backfacing)",
        count: |s| s.shadow_backfacing,
    },
    Saving {
        key: "shadow_unoccluded",
        short: "unocc",
        label: "shadow rays with no possible occluder (unoccluded)",
        count: |s| s.shadow_unoccluded,
    },
    Saving {
        key: "shadow_umbra",
        short: "umbra",
        label: "shadow rays inside one occluder's umbra",
        count: |s| s.shadow_umbra,
    },
    Saving {
        key: "shadow_unneeded",
        short: "unneed",
        label: "shadow rays no term needed (unneeded)",
        count: |s| s.shadow_unneeded,
    },
    Saving {
        key: "shadow_adaptive",
        short: "adapt",
        label: "shadow rays left out by adaptive sampling",
        count: |s| s.shadow_adaptive,
    },
];

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
        self.exact_hits += o.exact_hits;
        self.exact_fallbacks += o.exact_fallbacks;
    }
}
