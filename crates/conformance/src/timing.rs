//! The run's durations (a leaf module: the checks and the interop probes both use it).

/// Durations of the run, scaled to the peer's measured LowState period so that every window holds enough samples
/// whatever the rate (a 200 Hz peer gets as many samples per decision as the floors give a 500 Hz one, more at
/// lower rates).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Timing {
    /// Measured (or, failing that, nominal) LowState period (s).
    pub period: f64,
    /// Hold before each probe (s).
    pub hold: f64,
    /// One probe (s).
    pub probe: f64,
    /// Tail averaged for a settled value (s).
    pub tail: f64,
    /// Samples this soon after a command switch may still show the previous command (s).
    pub latency: f64,
    /// A LowState gap longer than this (s) means the stream was lost.
    pub gap_limit: f64,
    /// Observation after commands stop (s).
    pub silence: f64,
}

impl Timing {
    pub fn from_period(period: f64) -> Timing {
        let p = period.clamp(1e-4, 0.1);
        Timing {
            period: p,
            hold: (30.0 * p).max(0.3),
            probe: (40.0 * p).max(0.4),
            tail: (10.0 * p).max(0.1),
            latency: (3.0 * p).max(0.02),
            gap_limit: (10.0 * p).max(0.25),
            silence: (60.0 * p).max(1.0),
        }
    }
}
