//! How a shell sleeps until its machine's next wake-up: one timer per machine (quinn's
//! `TimerTable` in a single slot), moved only when the machine's `poll_timeout` moves, and rung
//! with the instant it was set for, which the machines' `handle_timeout` takes (a wake-up long
//! after it was due is a process that was stopped: `fleet::pause`). The clock is a trait, so
//! that the timer can be driven by a clock the test moves by hand.

use std::future::Future;
use std::pin::Pin;

use tcpf_core::time::Moment;

use crate::clock::Monotonic;

/// The clock a shell's machines run on: what time it is, and a timer that completes once it is
/// a given time.
pub trait Clock {
    type Timer: Future<Output = ()>;
    fn now(&self) -> Moment;
    fn timer(&self, at: Moment) -> Self::Timer;
    /// Moves `timer` to complete at `at` instead.
    fn reset(&self, timer: Pin<&mut Self::Timer>, at: Moment);
}

impl Clock for Monotonic {
    type Timer = tokio::time::Sleep;

    fn now(&self) -> Moment {
        Monotonic::now(self)
    }

    fn timer(&self, at: Moment) -> tokio::time::Sleep {
        tokio::time::sleep_until(self.at(at))
    }

    fn reset(&self, timer: Pin<&mut tokio::time::Sleep>, at: Moment) {
        timer.reset(self.at(at));
    }
}

pub struct Alarm<C: Clock> {
    clock: C,
    /// The instant the timer is set for, if it is set.
    due: Option<Moment>,
    timer: Pin<Box<C::Timer>>,
}

impl<C: Clock> Alarm<C> {
    pub fn new(clock: C) -> Alarm<C> {
        let timer = Box::pin(clock.timer(Moment::default()));
        Alarm {
            clock,
            due: None,
            timer,
        }
    }

    /// Sets the alarm for the machine's next wake-up, or unsets it (`None`). The timer is moved
    /// only if the instant changed: a loop sets it before every wait.
    pub fn set(&mut self, due: Option<Moment>) {
        if due != self.due {
            if let Some(at) = due {
                self.clock.reset(self.timer.as_mut(), at);
            }
            self.due = due;
        }
    }

    /// Completes once the clock reaches the instant the alarm is set for, with that instant;
    /// never while it is unset. Rung, it is unset. Dropped before it completes (a `select!`
    /// that went another way), it stays set.
    pub async fn rung(&mut self) -> Moment {
        let Some(due) = self.due else {
            return std::future::pending().await;
        };
        self.timer.as_mut().await;
        self.due = None;
        due
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use std::sync::Arc;
    use std::time::Duration;

    use tokio::sync::watch;

    use super::*;

    /// A clock that moves only when the test says.
    #[derive(Clone)]
    pub(crate) struct ByHand(Arc<watch::Sender<Moment>>);

    impl ByHand {
        pub(crate) fn at_zero() -> ByHand {
            ByHand(Arc::new(watch::channel(Moment::default()).0))
        }

        pub(crate) fn advance(&self, to: f64) {
            self.0.send_replace(Moment::from_secs(to));
        }
    }

    impl Clock for ByHand {
        type Timer = Pin<Box<dyn Future<Output = ()> + Send>>;

        fn now(&self) -> Moment {
            *self.0.borrow()
        }

        fn timer(&self, at: Moment) -> Self::Timer {
            let mut now = self.0.subscribe();
            Box::pin(async move {
                let _ = now.wait_for(|now| *now >= at).await;
            })
        }

        fn reset(&self, mut timer: Pin<&mut Self::Timer>, at: Moment) {
            timer.set(self.timer(at));
        }
    }

    fn at(s: f64) -> Moment {
        Moment::from_secs(s)
    }

    /// Whether the alarm rings without the clock moving, and with what.
    async fn rings(alarm: &mut Alarm<ByHand>) -> Option<Moment> {
        tokio::time::timeout(Duration::from_millis(20), alarm.rung()).await.ok()
    }

    #[tokio::test]
    async fn an_alarm_rings_when_the_clock_reaches_it_with_the_instant_it_was_set_for() {
        let clock = ByHand::at_zero();
        let mut alarm = Alarm::new(clock.clone());
        assert_eq!(rings(&mut alarm).await, None, "unset, it never rings");
        alarm.set(Some(at(2.0)));
        clock.advance(1.9);
        assert_eq!(rings(&mut alarm).await, None, "not yet");
        // Moved later, then back: it rings at the last instant set.
        alarm.set(Some(at(5.0)));
        clock.advance(3.0);
        assert_eq!(rings(&mut alarm).await, None, "moved past 3 s");
        alarm.set(Some(at(2.5)));
        assert_eq!(rings(&mut alarm).await, Some(at(2.5)), "already due: at once");
        assert_eq!(rings(&mut alarm).await, None, "rung, it is unset");
        // Reached long after it was due (a stopped process): it says when it was due.
        alarm.set(Some(at(4.0)));
        clock.advance(60.0);
        assert_eq!(rings(&mut alarm).await, Some(at(4.0)));
        assert_eq!(clock.now(), at(60.0));
        alarm.set(Some(at(70.0)));
        alarm.set(None);
        clock.advance(80.0);
        assert_eq!(rings(&mut alarm).await, None, "unset before it was due");
    }

    #[tokio::test]
    async fn on_the_monotonic_clock_an_alarm_set_again_for_the_same_instant_keeps_its_timer() {
        let clock = Monotonic::start();
        let mut alarm = Alarm::new(clock);
        let due = clock.now() + 0.05;
        alarm.set(Some(due));
        let deadline = alarm.timer.deadline();
        alarm.set(Some(due));
        assert_eq!(alarm.timer.deadline(), deadline);
        assert_eq!(alarm.rung().await, due);
        assert!(clock.now() >= due);
    }
}
