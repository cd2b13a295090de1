//! A progress bar for long runs: simulated time and ticks per second, on stderr when it is a
//! terminal; indicatif draws nothing otherwise.

use std::cell::Cell;

use indicatif::{ProgressBar, ProgressStyle};
use tcpf_core::mission::Mission;

pub struct Ticks {
    bar: ProgressBar,
    dt: f64,
    drawn: Cell<u64>,
}

impl Ticks {
    pub fn new(mission: &Mission) -> Ticks {
        let bar = ProgressBar::new(mission.max_ticks());
        bar.set_style(
            ProgressStyle::with_template("{bar:40} t = {msg} s  {per_sec} ticks  {elapsed}").expect("valid template"),
        );
        Ticks {
            bar,
            dt: mission.mission.control_period,
            drawn: Cell::new(0),
        }
    }

    /// Ticks so far; redraws once 64 more have passed (a recorder may complete several ticks at
    /// once), which keeps it off the hot path.
    pub fn set(&self, ticks: u64) {
        if ticks >= self.drawn.get() + 64 {
            self.drawn.set(ticks);
            self.bar.set_position(ticks);
            self.bar.set_message(format!("{:.1}", ticks as f64 * self.dt));
        }
    }

    pub fn finish(&self) {
        self.bar.finish_and_clear();
    }
}
