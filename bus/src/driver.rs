//! The one loop of every role's process: it runs a core `Machine` on a `Clock`, its inputs and
//! outputs carried by the role's `Wiring`. The wiring turns Zenoh's samples, liveliness changes
//! and signals into the machine's inputs, and performs its outputs; the driver keeps the time:
//! it stamps every input with `now`, sleeps on one `Alarm` until the machine's next wake-up, and
//! asks for the exit once every output is done. A role's shell is then its machine, its wiring
//! and this call.

use std::future::Future;

use tcpf_core::roles::machine::Machine;

use crate::alarm::{Alarm, Clock};

/// How a role's process hears and acts for its machine.
pub trait Wiring<M: Machine> {
    type Error;

    /// The next input: a message, a liveliness change, a signal. It must be cancel-safe (a
    /// `tokio::select!` of channel receives is): the driver drops it when the alarm rings first.
    fn next(&mut self) -> impl Future<Output = M::Input>;

    /// Does what the machine asked, reading what it lends (a tick's states, which a queue of
    /// owned outputs would copy). What came of it, if the machine is to know (an agent started
    /// again, or not), is its next input.
    fn perform(
        &mut self,
        output: M::Output,
        machine: &M,
    ) -> impl Future<Output = Result<Option<M::Input>, Self::Error>>;

    /// What the wiring can only look at, not be told of (a child's exit status): looked at as
    /// the machine wakes, and given to it before the wake-up.
    fn looked(&mut self) -> Vec<M::Input> {
        Vec::new()
    }
}

/// Runs `machine` until it exits, or an output fails.
pub async fn drive<M, W, C>(machine: &mut M, wiring: &mut W, clock: C) -> Result<M::Exit, W::Error>
where
    M: Machine,
    W: Wiring<M>,
    C: Clock + Clone,
{
    let mut alarm = Alarm::new(clock.clone());
    loop {
        while let Some(output) = machine.poll_output() {
            if let Some(input) = wiring.perform(output, machine).await? {
                machine.handle(input, clock.now());
            }
        }
        if let Some(exit) = machine.poll_exit() {
            return Ok(exit);
        }
        alarm.set(machine.poll_timeout());
        tokio::select! {
            input = wiring.next() => machine.handle(input, clock.now()),
            due = alarm.rung() => {
                for input in wiring.looked() {
                    machine.handle(input, clock.now());
                }
                machine.handle_timeout(clock.now(), due);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use std::sync::{Arc, Mutex};
    use std::time::Duration;

    use tcpf_core::time::Moment;
    use tokio::sync::mpsc;

    use super::*;
    use crate::alarm::tests::ByHand;

    /// A watchdog: it says each word it hears, wants to be woken `patience` after the last, and
    /// exits at the wake-up with how long it had waited past it.
    struct Watchdog {
        patience: f64,
        last: Option<Moment>,
        said: Vec<String>,
        exit: Option<(Moment, Moment)>,
    }

    #[derive(Debug, PartialEq)]
    enum Heard {
        Word(&'static str),
        /// What came of saying a word.
        Echo(String),
        /// What the wiring looked at before a wake-up.
        Looked,
    }

    impl Machine for Watchdog {
        type Input = Heard;
        type Output = String;
        /// When it was due, when it woke.
        type Exit = (Moment, Moment);

        fn handle(&mut self, input: Heard, now: Moment) {
            match input {
                Heard::Word(word) => {
                    self.last = Some(now);
                    self.said.push(format!("{word}@{}", now.secs()));
                }
                Heard::Echo(_) | Heard::Looked => {}
            }
        }

        fn poll_timeout(&self) -> Option<Moment> {
            self.last.map(|last| last + self.patience)
        }

        fn handle_timeout(&mut self, now: Moment, due: Moment) {
            self.exit = Some((due, now));
        }

        fn poll_output(&mut self) -> Option<String> {
            (!self.said.is_empty()).then(|| self.said.remove(0))
        }

        fn poll_exit(&mut self) -> Option<(Moment, Moment)> {
            self.exit
        }
    }

    /// Words from the test; what the watchdog says and the inputs it is given, in one log.
    struct Script {
        words: mpsc::UnboundedReceiver<&'static str>,
        log: Arc<Mutex<Vec<Heard>>>,
    }

    impl Wiring<Watchdog> for Script {
        type Error = String;

        async fn next(&mut self) -> Heard {
            match self.words.recv().await {
                Some(word) => Heard::Word(word),
                None => std::future::pending().await,
            }
        }

        async fn perform(&mut self, said: String, _: &Watchdog) -> Result<Option<Heard>, String> {
            if said.starts_with("fail") {
                return Err(said);
            }
            self.log.lock().unwrap().push(Heard::Echo(said.clone()));
            Ok(Some(Heard::Echo(said)))
        }

        fn looked(&mut self) -> Vec<Heard> {
            self.log.lock().unwrap().push(Heard::Looked);
            vec![Heard::Looked]
        }
    }

    fn at(s: f64) -> Moment {
        Moment::from_secs(s)
    }

    /// Lets the driver's task run to its next wait.
    async fn settle() {
        tokio::time::sleep(Duration::from_millis(20)).await;
    }

    #[tokio::test]
    async fn the_driver_stamps_inputs_performs_outputs_and_wakes_its_machine_when_it_asked_on_the_clock_given() {
        let clock = ByHand::at_zero();
        let (say, words) = mpsc::unbounded_channel();
        let log = Arc::new(Mutex::new(Vec::new()));
        let mut wiring = Script {
            words,
            log: log.clone(),
        };
        let mut machine = Watchdog {
            patience: 1.0,
            last: None,
            said: Vec::new(),
            exit: None,
        };
        let driven = tokio::spawn({
            let clock = clock.clone();
            async move { drive(&mut machine, &mut wiring, clock).await }
        });
        settle().await;
        clock.advance(100.0);
        settle().await;
        assert!(log.lock().unwrap().is_empty(), "no wake-up asked for: none comes");

        say.send("a").unwrap();
        settle().await;
        clock.advance(100.5);
        say.send("b").unwrap();
        settle().await;
        // The wake-up moved with the last word: from 101 s to 101.5 s.
        clock.advance(101.2);
        settle().await;
        assert!(!driven.is_finished(), "woken at 101 s, for a word it heard later");
        assert_eq!(
            *log.lock().unwrap(),
            [Heard::Echo("a@100".into()), Heard::Echo("b@100.5".into())],
            "each word stamped with the clock as it came, said once"
        );
        // Reached long after it was due (a stopped process): the machine is told both.
        clock.advance(130.0);
        let exit = tokio::time::timeout(Duration::from_secs(5), driven)
            .await
            .unwrap()
            .unwrap();
        assert_eq!(exit, Ok((at(101.5), at(130.0))));
        assert_eq!(
            log.lock().unwrap().last(),
            Some(&Heard::Looked),
            "looked at before the wake-up"
        );
    }

    #[tokio::test]
    async fn an_output_that_fails_ends_the_drive_with_its_error() {
        let (say, words) = mpsc::unbounded_channel();
        let mut wiring = Script {
            words,
            log: Arc::default(),
        };
        let mut machine = Watchdog {
            patience: 1.0,
            last: None,
            said: Vec::new(),
            exit: None,
        };
        say.send("failing").unwrap();
        let driven = drive(&mut machine, &mut wiring, ByHand::at_zero());
        let ended = tokio::time::timeout(Duration::from_secs(5), driven).await.unwrap();
        assert_eq!(ended, Err("failing@0".to_string()));
    }
}
