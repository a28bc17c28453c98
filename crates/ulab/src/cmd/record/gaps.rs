//! Gap statistics of one recorded topic in bounded memory.
//!
//! The end-of-recording report needs typical periods (medians). A median over the whole run would keep every
//! arrival (8 bytes) and LowState tick (16 bytes) in memory: 16 kB a second for both topics at 500 Hz, 1.4 GB a
//! day. So the arrivals are judged in blocks of [`BLOCK`] messages (about a minute at 500 Hz): each block's gaps
//! are found against that block's own median period and only the findings and a per-second message count are
//! kept. A recording shorter than one block is judged against the median of the whole run.

/// Messages per judged block.
pub const BLOCK: usize = 32_768;
/// Gap lines kept for the report (the count covers all of them).
const MAX_KEPT: usize = 30;
/// A final block shorter than this borrows the previous block's period, whose median is better founded.
const MIN_OWN_MEDIAN: usize = 64;

/// Running gap statistics of one topic.
#[derive(Debug, Default)]
pub struct GapStats {
    /// Messages seen.
    count: u64,
    first_ns: Option<i64>,
    last_ns: Option<i64>,
    /// Arrivals of the open block; element 0 is message `block_index` (the previous block's last arrival, so that
    /// the interval across the boundary is judged too).
    block: Vec<i64>,
    block_index: u64,
    /// `(arrival, tick)` of the open block's decodable LowStates; element 0 is tick sample `tick_index`.
    ticks: Vec<(i64, u32)>,
    tick_index: u64,
    /// Messages per whole second since the first arrival, for the rate-drop check.
    per_second: Vec<u32>,
    undecodable: u64,
    /// Median arrival interval of the last judged block.
    last_period: Option<i64>,
    /// Median positive tick step of the last judged block.
    last_step: Option<i64>,
    /// Tick steps seen, with how many blocks had each (the report names the most common).
    steps: Vec<(i64, u64)>,
    tick_jumps: u64,
    missing_by_tick: i64,
    findings: u64,
    kept: Vec<String>,
}

fn median(v: &mut [i64]) -> Option<i64> {
    if v.is_empty() {
        return None;
    }
    v.sort_unstable();
    Some(v[v.len() / 2])
}

impl GapStats {
    /// Messages seen so far.
    pub fn count(&self) -> u64 {
        self.count
    }

    /// Records one arrival (reception time in ns) and, for LowState topics, its tick (`Some(None)`: a LowState
    /// that did not decode).
    pub fn push(&mut self, arrival_ns: i64, tick: Option<Option<u32>>) {
        self.count += 1;
        let first = *self.first_ns.get_or_insert(arrival_ns);
        self.last_ns = Some(arrival_ns);
        if let Ok(second) = usize::try_from((arrival_ns - first) / 1_000_000_000) {
            // A clock step back or forward by more than a day is not a rate; do not allocate for it.
            if second < 86_400 * 7 {
                if self.per_second.len() <= second {
                    self.per_second.resize(second + 1, 0);
                }
                self.per_second[second] += 1;
            }
        }
        if self.block.capacity() == 0 {
            // Exactly one block (plus the carried arrival): doubling would hold twice that.
            self.block.reserve_exact(BLOCK + 1);
        }
        self.block.push(arrival_ns);
        match tick {
            Some(Some(t)) => {
                if self.ticks.capacity() == 0 {
                    self.ticks.reserve_exact(BLOCK + 1);
                }
                self.ticks.push((arrival_ns, t));
            }
            Some(None) => self.undecodable += 1,
            None => {}
        }
        if self.block.len() > BLOCK {
            self.judge_block(false);
        }
        if self.ticks.len() > BLOCK {
            self.judge_ticks(false);
        }
    }

    fn note(&mut self, text: String) {
        self.findings += 1;
        if self.kept.len() < MAX_KEPT {
            self.kept.push(text);
        }
    }

    /// Judges the open block of arrivals and keeps its last arrival as the start of the next one.
    fn judge_block(&mut self, last: bool) {
        let dts: Vec<i64> = self.block.windows(2).map(|w| w[1] - w[0]).collect();
        let own = if last && dts.len() < MIN_OWN_MEDIAN && self.last_period.is_some() {
            None
        } else {
            median(&mut dts.clone())
        };
        if let Some(med) = own.or(self.last_period) {
            self.last_period = Some(med);
            let limit = (5 * med).max(20_000_000);
            for (i, dt) in dts.iter().enumerate() {
                if *dt > limit {
                    self.note(format!(
                        "arrival gap of {:.1} ms after message {} (typical {:.2} ms)",
                        *dt as f64 / 1e6,
                        self.block_index + i as u64,
                        med as f64 / 1e6
                    ));
                }
            }
        }
        if let Some(&tail) = self.block.last() {
            self.block_index += self.block.len() as u64 - 1;
            self.block.clear();
            self.block.push(tail);
        }
    }

    /// Judges the open block of LowState ticks and keeps its last tick as the start of the next one.
    fn judge_ticks(&mut self, last: bool) {
        let deltas: Vec<i64> = self.ticks.windows(2).map(|w| i64::from(w[1].1) - i64::from(w[0].1)).collect();
        let mut positive: Vec<i64> = deltas.iter().copied().filter(|d| *d > 0).collect();
        let own = if last && positive.len() < MIN_OWN_MEDIAN && self.last_step.is_some() {
            None
        } else {
            median(&mut positive)
        };
        if let Some(step) = own.or(self.last_step) {
            self.last_step = Some(step);
            match self.steps.iter_mut().find(|(s, _)| *s == step) {
                Some((_, n)) => *n += 1,
                None => self.steps.push((step, 1)),
            }
            for (i, d) in deltas.iter().enumerate() {
                if *d <= 0 || *d > step + step / 2 {
                    self.tick_jumps += 1;
                    if *d > 0 {
                        self.missing_by_tick += d / step - 1;
                    }
                    let text = format!(
                        "tick jump {} -> {} ({:+}, step {step}) at message {}",
                        self.ticks[i].1,
                        self.ticks[i + 1].1,
                        d,
                        self.tick_index + i as u64 + 1
                    );
                    self.note(text);
                }
            }
        }
        if let Some(&tail) = self.ticks.last() {
            self.tick_index += self.ticks.len() as u64 - 1;
            self.ticks.clear();
            self.ticks.push(tail);
        }
    }

    /// Elements held in memory (bounded by two blocks plus one count per recorded second).
    #[cfg(test)]
    fn held(&self) -> usize {
        self.block.capacity() + self.ticks.capacity() + self.per_second.capacity() + self.kept.capacity()
    }

    /// Finishes the statistics and appends this topic's lines to the report `t`.
    pub fn report(mut self, name: &str, max_listed: usize, t: &mut String) {
        let n = self.count;
        let (Some(first), Some(last)) = (self.first_ns, self.last_ns) else {
            t.push_str(&format!("{name}: 0 messages\n"));
            return;
        };
        let span = (last - first) as f64 / 1e9;
        let rate = if span > 0.0 { (n - 1) as f64 / span } else { 0.0 };
        t.push_str(&format!("{name}: {n} messages, {rate:.1} Hz over {span:.2} s\n"));
        if self.block.len() > 1 {
            self.judge_block(true);
        }
        if self.ticks.len() > 1 {
            self.judge_ticks(true);
        }
        if let Some((step, _)) = self.steps.iter().max_by_key(|(_, blocks)| *blocks) {
            t.push_str(&format!(
                "  tick step {step}, {} tick jumps, about {} samples missing by tick\n",
                self.tick_jumps, self.missing_by_tick
            ));
        }
        if self.undecodable > 0 {
            t.push_str(&format!("  {} samples did not decode (no tick)\n", self.undecodable));
        }
        // Rate drops: full one-second windows under half the median window count.
        let whole = usize::try_from((last - first) / 1_000_000_000).unwrap_or(0).min(self.per_second.len());
        if whole >= 3 {
            let counts: Vec<i64> = self.per_second[..whole].iter().map(|c| i64::from(*c)).collect();
            if let Some(med) = median(&mut counts.clone()) {
                for (w, c) in counts.iter().enumerate() {
                    if *c * 2 < med {
                        self.note(format!("rate drop to {c} Hz in second {w} (typical {med} Hz)"));
                    }
                }
            }
        }
        if self.findings == 0 {
            t.push_str("  no gaps detected\n");
        } else {
            t.push_str(&format!("  {} gap findings:\n", self.findings));
            for g in self.kept.iter().take(max_listed) {
                t.push_str(&format!("  gap: {g}\n"));
            }
            if self.findings > max_listed as u64 {
                t.push_str(&format!("  ... {} more\n", self.findings - max_listed as u64));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const PERIOD: i64 = 2_000_000; // 500 Hz

    fn report(s: GapStats) -> String {
        let mut t = String::new();
        s.report("rt/lowstate", 10, &mut t);
        t
    }

    #[test]
    fn memory_stays_bounded_over_an_hour_at_500_hz() {
        let mut s = GapStats::default();
        let mut peak = 0;
        for i in 0..(500 * 3600) {
            s.push(i * PERIOD, Some(Some((2 * i) as u32)));
            peak = peak.max(s.held());
        }
        // Two blocks of arrivals and ticks, one count per second, the kept lines; the old design held
        // 1.8 million arrivals and ticks here.
        assert!(peak < 3 * (BLOCK + 1) + 8_000, "held {peak} elements");
        let t = report(s);
        assert!(t.contains("1800000 messages, 500.0 Hz over 3600.00 s"), "{t}");
        assert!(t.contains("tick step 2, 0 tick jumps, about 0 samples missing by tick"), "{t}");
        assert!(t.contains("no gaps detected"), "{t}");
    }

    #[test]
    fn outage_across_a_block_boundary_is_found_with_its_global_index() {
        let mut s = GapStats::default();
        let mut t_ns = 0;
        let mut tick = 0u32;
        // The outage (50 ms, 25 samples) falls on the interval that crosses the first block boundary (message
        // BLOCK is the last of block one and the first of block two), and later inside the third block.
        for i in 0..(3 * BLOCK as u64 + 100) {
            let outage = i == BLOCK as u64 + 1 || i == 2 * BLOCK as u64 + 7;
            if outage {
                t_ns += 25 * PERIOD;
                tick += 50;
            }
            s.push(t_ns, Some(Some(tick)));
            t_ns += PERIOD;
            tick += 2;
        }
        let t = report(s);
        let first = BLOCK as u64;
        let second = 2 * BLOCK as u64 + 6;
        assert!(t.contains(&format!("arrival gap of 52.0 ms after message {first} (typical 2.00 ms)")), "{t}");
        assert!(t.contains(&format!("arrival gap of 52.0 ms after message {second} (typical 2.00 ms)")), "{t}");
        assert!(t.contains("tick step 2, 2 tick jumps, about 50 samples missing by tick"), "{t}");
        assert!(t.contains(&format!("at message {}", first + 1)), "{t}");
        assert!(t.contains(&format!("at message {}", second + 1)), "{t}");
        assert!(t.contains("  4 gap findings:"), "{t}");
    }

    #[test]
    fn a_short_final_block_borrows_the_previous_period() {
        let mut s = GapStats::default();
        for i in 0..(BLOCK as i64 + 10) {
            s.push(i * PERIOD, None);
        }
        // Three messages 30 ms apart after the last full block: gaps against 2 ms, but they would be
        // "typical" against their own median.
        let end = (BLOCK as i64 + 9) * PERIOD;
        for k in 1..=3 {
            s.push(end + k * 30_000_000, None);
        }
        let t = report(s);
        assert!(t.contains("3 gap findings"), "{t}");
        assert!(t.contains("arrival gap of 30.0 ms"), "{t}");
    }

    #[test]
    fn a_rate_drop_is_found_from_the_per_second_counts() {
        let mut s = GapStats::default();
        let mut t_ns = 0;
        for second in 0..10 {
            let n = if second == 4 { 100 } else { 500 };
            for k in 0..n {
                s.push(t_ns + k * (1_000_000_000 / n), None);
            }
            t_ns += 1_000_000_000;
        }
        let t = report(s);
        assert!(t.contains("rate drop to 100 Hz in second 4 (typical 500 Hz)"), "{t}");
    }

    #[test]
    fn empty_and_single_message_topics_report_without_dividing_by_zero() {
        assert_eq!(report(GapStats::default()), "rt/lowstate: 0 messages\n");
        let mut s = GapStats::default();
        s.push(5, Some(None));
        let t = report(s);
        assert!(t.contains("1 messages, 0.0 Hz over 0.00 s"), "{t}");
        assert!(t.contains("1 samples did not decode"), "{t}");
    }
}
