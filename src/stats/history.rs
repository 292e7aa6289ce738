//! Rates of each link: per second over the last interval, and a ring of the last
//! [`HISTORY_LEN`] one-second samples for the status page's charts.

use std::collections::{HashMap, VecDeque};

use super::snapshot::LinkStats;

/// Samples kept per link: five minutes at one a second.
pub const HISTORY_LEN: usize = 300;

#[derive(Debug, Clone, Default)]
struct LinkHistory {
    frames_in: u64,
    bytes_in: u64,
    frames_out: u64,
    bytes_out: u64,
    in_fps: VecDeque<f64>,
    out_fps: VecDeque<f64>,
}

/// The counters each link had at the last sample, and its rate ring.
#[derive(Debug, Clone, Default)]
pub struct History {
    last_s: Option<f64>,
    links: HashMap<u64, LinkHistory>,
}

impl History {
    /// Seconds since the previous sample (0 at the first), and notes `now_s` as the
    /// latest sample time.
    pub(crate) fn interval(&mut self, now_s: f64) -> f64 {
        let dt = self.last_s.map_or(0.0, |t| (now_s - t).max(0.0));
        self.last_s = Some(now_s);
        dt
    }

    /// Fills the rates and history of `links` from their counters over the last `dt`
    /// seconds (a link new since the last sample counts from zero), and forgets links
    /// that are gone. With `dt` zero (the first sample) the rates are zero.
    pub(crate) fn sample(&mut self, dt: f64, links: &mut [LinkStats]) {
        let mut next = HashMap::with_capacity(links.len());
        for l in links.iter_mut() {
            let mut h = self.links.remove(&l.id).unwrap_or_default();
            let rate = |now: u64, then: u64, scale: f64| {
                if dt > 0.0 {
                    now.saturating_sub(then) as f64 * scale / dt
                } else {
                    0.0
                }
            };
            l.rate_in_fps = rate(l.frames_in, h.frames_in, 1.0);
            l.rate_out_fps = rate(l.frames_out, h.frames_out, 1.0);
            l.rate_in_bps = rate(l.bytes_in, h.bytes_in, 8.0);
            l.rate_out_bps = rate(l.bytes_out, h.bytes_out, 8.0);
            h.frames_in = l.frames_in;
            h.bytes_in = l.bytes_in;
            h.frames_out = l.frames_out;
            h.bytes_out = l.bytes_out;
            if dt > 0.0 {
                push(&mut h.in_fps, l.rate_in_fps);
                push(&mut h.out_fps, l.rate_out_fps);
            }
            l.history_in_fps = h.in_fps.iter().copied().collect();
            l.history_out_fps = h.out_fps.iter().copied().collect();
            next.insert(l.id, h);
        }
        self.links = next;
    }
}

fn push(ring: &mut VecDeque<f64>, v: f64) {
    if ring.len() >= HISTORY_LEN {
        ring.pop_front();
    }
    ring.push_back(v);
}

#[cfg(test)]
mod tests {
    use super::*;

    fn link(id: u64, frames_in: u64, bytes_in: u64) -> LinkStats {
        LinkStats {
            id,
            frames_in,
            bytes_in,
            ..LinkStats::default()
        }
    }

    #[test]
    fn rates_follow_the_counters_and_the_ring_is_bounded() {
        let mut h = History::default();
        let dt = h.interval(0.0);
        let mut l = [link(1, 0, 0)];
        h.sample(dt, &mut l);
        assert_eq!(l[0].rate_in_fps, 0.0);
        assert!(l[0].history_in_fps.is_empty());
        let dt = h.interval(2.0);
        let mut l = [link(1, 20, 680)];
        h.sample(dt, &mut l);
        assert_eq!(l[0].rate_in_fps, 10.0);
        assert_eq!(l[0].rate_in_bps, 2720.0);
        assert_eq!(l[0].history_in_fps, vec![10.0]);
        for s in 0..400u64 {
            let dt = h.interval(3.0 + s as f64);
            let mut l = [link(1, 20 + s, 680)];
            h.sample(dt, &mut l);
            assert!(l[0].history_in_fps.len() <= HISTORY_LEN);
        }
        // A link that is gone is forgotten; a new one starts from zero.
        let dt = h.interval(500.0);
        let mut l = [link(2, 5, 5)];
        h.sample(dt, &mut l);
        assert_eq!(h.links.len(), 1);
        assert_eq!(l[0].history_in_fps.len(), 1);
    }
}
