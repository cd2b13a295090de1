//! The key expressions of docs/PROTOCOL.md, in one place. `<m>` is the mission name.

use std::fmt;

pub use tcpf_core::msg::Role;

#[derive(Debug, Clone)]
pub struct Keys {
    root: String,
}

impl Keys {
    pub fn new(mission: &str) -> Keys {
        Keys {
            root: format!("tcpf/{mission}"),
        }
    }

    fn key(&self, kind: &str, id: impl fmt::Display) -> String {
        format!("{}/{kind}/{id}", self.root)
    }

    pub fn plan(&self, id: impl fmt::Display) -> String {
        self.key("plan", id)
    }
    pub fn state(&self, id: impl fmt::Display) -> String {
        self.key("state", id)
    }
    pub fn cmd(&self, id: impl fmt::Display) -> String {
        self.key("cmd", id)
    }
    pub fn gamma(&self, id: impl fmt::Display) -> String {
        self.key("gamma", id)
    }
    pub fn alive(&self, role: Role, id: impl fmt::Display) -> String {
        format!("{}/alive/{role}/{id}", self.root)
    }
    /// A process's claim of a role only one may hold (`tcpf_core::fleet::claim`), as a liveliness token.
    pub fn claim(&self, role: Role, id: impl fmt::Display, chunk: &str) -> String {
        format!("{}/claim/{role}/{id}/{chunk}", self.root)
    }
    /// Every claim of a role.
    pub fn claims(&self, role: Role, id: impl fmt::Display) -> String {
        format!("{}/claim/{role}/{id}/*", self.root)
    }
    /// Every key of the mission.
    pub fn all(&self) -> String {
        format!("{}/**", self.root)
    }

    /// Every liveliness token of the mission.
    pub fn alive_all(&self) -> String {
        format!("{}/alive/**", self.root)
    }
    /// The world's announcement that it gave up on a vehicle's agent.
    pub fn lost(&self, id: impl fmt::Display) -> String {
        self.key("lost", id)
    }

    /// The world's clock (a queryable, once the run has started).
    pub fn clock(&self) -> String {
        format!("{}/clock", self.root)
    }

    /// The lockstep world's record of each tick it closed, for recorders.
    pub fn tick(&self) -> String {
        format!("{}/tick", self.root)
    }

    /// The realtime world's history of the states it ran, which a recorder fetches what it
    /// missed from (a queryable).
    pub fn history(&self) -> String {
        format!("{}/history", self.root)
    }

    pub fn end(&self) -> String {
        format!("{}/end", self.root)
    }
    pub fn report(&self, role: Role, id: impl fmt::Display) -> String {
        format!("{}/report/{role}/{id}", self.root)
    }

    /// Every role's exit report.
    pub fn reports(&self) -> String {
        format!("{}/report/**", self.root)
    }

    /// (role, id) of a liveliness key of this mission.
    pub fn parse_alive(&self, key: &str) -> Option<(Role, u32)> {
        let rest = key.strip_prefix(&self.root)?.strip_prefix("/alive/")?;
        let (role, id) = rest.split_once('/')?;
        Some((Role::parse(role)?, id.parse().ok()?))
    }

    /// The trailing id of a per-vehicle key.
    pub fn id_of(key: &str) -> Option<u32> {
        key.rsplit('/').next()?.parse().ok()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_follow_the_design() {
        let k = Keys::new("paper-b-current");
        assert_eq!(k.plan(2), "tcpf/paper-b-current/plan/2");
        assert_eq!(k.state(2), "tcpf/paper-b-current/state/2");
        assert_eq!(k.cmd("*"), "tcpf/paper-b-current/cmd/*");
        assert_eq!(k.gamma(1), "tcpf/paper-b-current/gamma/1");
        assert_eq!(k.tick(), "tcpf/paper-b-current/tick");
        assert_eq!(k.history(), "tcpf/paper-b-current/history");
        assert_eq!(k.alive(Role::Agent, 3), "tcpf/paper-b-current/alive/agent/3");
        assert_eq!(
            k.parse_alive("tcpf/paper-b-current/alive/world/0"),
            Some((Role::World, 0))
        );
        assert_eq!(k.parse_alive("tcpf/other/alive/world/0"), None);
        assert_eq!(Keys::id_of("tcpf/m/cmd/12"), Some(12));
    }
}
