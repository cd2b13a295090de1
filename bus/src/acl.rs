//! The router's access rules, made from the mission: every identity (`Identity`: the user a role
//! authenticates as, or the Common Name of its certificate) may do only what its role needs, and anything else is denied where
//! it enters the router. Every role must therefore be a client of that router, never a peer of
//! another: access control is enforced where a message passes.
//!
//! What each may send (ingress):
//! - everyone may subscribe, watch liveliness, and ask for paths, the clock and the world's
//!   history (listening says nothing in anyone's name);
//! - the world: everything (in `tcpf run` it is the router, whose own messages no rule stops);
//! - the planner: paths (published, and as answers to `plan/<id>`), its token, its exit report;
//! - agent N: its own commands and γ, its own tokens (alive, claim), its own exit report, and as
//!   the ROS 2 node `agent_N` its vehicle's commands;
//! - a recorder: its token, and acknowledgements of what is handed over to it (exit reports, the
//!   end, losses);
//! - vehicle N played by a ROS 2 node (`vehicle_N`): its odometry;
//! - an observer: nothing; with ROS 2, an observer or a recorder may also declare what a ROS 2
//!   node that listens declares in the graph (its node, its subscriptions), but never a token of
//!   the fleet's own nodes (`world`, `agent_N`, `vehicle_N`), which say who plays a vehicle.
//!
//! Everyone may hear everything of the fleet (egress): the fleet keeps no secrets from its own
//! members, only its words from being forged.

use std::fmt;

use serde_json::{json, Value};
use tcpf_core::mission::Ros2Config;

use crate::keys::{Keys, Role};

/// Who a process speaks for: the role it may play, and nothing else.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Identity {
    /// The world: it alone publishes states, tick records, the end and losses, and keeps the clock.
    World,
    /// The planner: it alone answers `plan/<id>`.
    Planner,
    /// Vehicle N's agent: its commands, its γ, its exit report.
    Agent(u32),
    /// A recorder: it listens, and acknowledges what is handed over to it.
    Recorder,
    /// An observer (a viewer, `ros2 topic echo`, a probe): it only listens.
    Observer,
    /// Vehicle N played by another program: its states, or as a ROS 2 node its odometry.
    Vehicle(u32),
}

impl fmt::Display for Identity {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Identity::World => f.write_str("world"),
            Identity::Planner => f.write_str("planner"),
            Identity::Agent(id) => write!(f, "agent-{id}"),
            Identity::Recorder => f.write_str("recorder"),
            Identity::Observer => f.write_str("observer"),
            Identity::Vehicle(id) => write!(f, "vehicle-{id}"),
        }
    }
}

/// How the router knows a link's identity.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Naming {
    /// The user it authenticated as (Zenoh's user-password authentication).
    Username,
    /// The Common Name of its certificate (mutual TLS).
    CommonName,
}

/// Every kind of message Zenoh's access control knows.
const ALL: [&str; 9] = [
    "put",
    "delete",
    "query",
    "reply",
    "declare_subscriber",
    "declare_queryable",
    "liveliness_token",
    "liveliness_query",
    "declare_liveliness_subscriber",
];

/// The fleet the rules are made for.
pub struct Fleet<'a> {
    /// The mission's keys (`Keys::new("*")` for rules that fit any mission of the fleet).
    pub keys: Keys,
    pub vehicles: &'a [u32],
    /// The fleet's ROS 2 graph, if it speaks ROS 2.
    pub ros2: Option<&'a Ros2Config>,
    /// The vehicles other programs may play on the fleet's own protocol (their states; a world
    /// started by hand with `--vehicles` simulates the others).
    pub played: &'a [u32],
}

impl Fleet<'_> {
    /// Every key of the fleet: its own and its ROS 2 domain's, data, history and tokens (a ROS 2
    /// tool listens to the whole domain: `/clock` is at its root). `**` does not reach a chunk
    /// that starts with `@`, so the history's (`<key>/@adv/...`) is named on its own.
    fn all(&self) -> Vec<String> {
        let mut keys = vec![self.keys.all()];
        if let Some(ros2) = self.ros2 {
            keys.extend([
                format!("{}/**", ros2.domain),
                format!("{}/**/@adv/**", ros2.domain),
                format!("@ros2_lv/{}/**", ros2.domain),
            ]);
        }
        keys
    }
}

fn rule(id: &str, flow: &str, messages: &[&str], key_exprs: Vec<String>) -> Value {
    json!({
        "id": id,
        "permission": "allow",
        "flows": [flow],
        "messages": messages,
        "key_exprs": key_exprs,
    })
}

/// A rule an identity acts by, beyond listening: `(name, messages, keys)`, ingress.
type Act = (String, Vec<&'static str>, Vec<String>);

/// The rules `identity` may act by, beyond listening.
fn speaks(fleet: &Fleet, identity: Identity) -> Vec<Act> {
    match identity {
        Identity::World => vec![("all".into(), ALL.to_vec(), fleet.all())],
        Identity::Planner => vec![
            (
                "paths".into(),
                vec!["put", "declare_queryable", "reply"],
                vec![fleet.keys.plan("*")],
            ),
            (
                "token".into(),
                vec!["liveliness_token"],
                vec![fleet.keys.alive(Role::Planner, "*")],
            ),
            (
                "report".into(),
                vec!["query"],
                vec![fleet.keys.report(Role::Planner, "*")],
            ),
        ],
        Identity::Agent(id) => {
            let mut rules = vec![
                (
                    "words".into(),
                    vec!["put"],
                    vec![fleet.keys.cmd(id), fleet.keys.gamma(id)],
                ),
                (
                    "tokens".into(),
                    vec!["liveliness_token"],
                    vec![fleet.keys.alive(Role::Agent, id), fleet.keys.claims(Role::Agent, id)],
                ),
                ("report".into(), vec!["query"], vec![fleet.keys.report(Role::Agent, id)]),
            ];
            if let Some(ros2) = fleet.ros2 {
                rules.extend(ros2_node(ros2, &format!("agent_{id}"), &ros2.command_topic(id)));
            }
            rules
        }
        Identity::Recorder => vec![
            (
                "acknowledge".into(),
                vec!["declare_queryable", "reply"],
                vec![fleet.keys.reports(), fleet.keys.end(), fleet.keys.lost("*")],
            ),
            (
                "token".into(),
                vec!["liveliness_token"],
                vec![fleet.keys.alive(Role::Record, "*")],
            ),
        ],
        Identity::Vehicle(id) => {
            let mut rules = Vec::new();
            if fleet.played.contains(&id) {
                rules.push(("states".into(), vec!["put"], vec![fleet.keys.state(id)]));
            }
            if let Some(ros2) = fleet.ros2 {
                rules.extend(ros2_node(ros2, &format!("vehicle_{id}"), &ros2.odometry_topic(id)));
            }
            rules
        }
        Identity::Observer => Vec::new(),
    }
}

/// What the fleet's ROS 2 node `node` does, beyond listening: publish `topic`, and declare
/// itself and its entities in the graph.
fn ros2_node(ros2: &Ros2Config, node: &str, topic: &str) -> [Act; 2] {
    [
        ("ros2-topic".into(), vec!["put"], vec![ros2.topic_keys(topic)]),
        (
            "ros2-node".into(),
            vec!["liveliness_token"],
            ros2.node_tokens(node).to_vec(),
        ),
    ]
}

/// The tokens of the fleet's own ROS 2 nodes (the world, `agent_N`, `vehicle_N`) and their
/// entities.
fn fleet_nodes(ros2: &Ros2Config) -> Vec<String> {
    ["world", "agent_$*", "vehicle_$*"]
        .iter()
        .flat_map(|node| ros2.node_tokens(node))
        .collect()
}

/// Every identity of the fleet.
pub fn identities(fleet: &Fleet) -> Vec<Identity> {
    let mut all = vec![
        Identity::World,
        Identity::Planner,
        Identity::Recorder,
        Identity::Observer,
    ];
    all.extend(fleet.vehicles.iter().map(|&id| Identity::Agent(id)));
    all.extend(
        fleet
            .vehicles
            .iter()
            .filter(|id| fleet.ros2.is_some() || fleet.played.contains(id))
            .map(|&id| Identity::Vehicle(id)),
    );
    all
}

/// The router's `access_control` section for `fleet`, knowing each identity by `naming`: deny by
/// default, and allow each identity what its role needs.
pub fn access_control(fleet: &Fleet, naming: Naming) -> Value {
    let mut ask_keys = vec![fleet.keys.plan("*"), fleet.keys.clock(), fleet.keys.history()];
    if let Some(ros2) = fleet.ros2 {
        // A transient-local subscription asks for what was published before it came.
        ask_keys.push(format!("{}/@adv/**", ros2.topic_keys(&ros2.namespace)));
    }
    let mut rules = vec![
        rule("hear", "egress", &ALL, fleet.all()),
        rule(
            "listen",
            "ingress",
            &[
                "declare_subscriber",
                "declare_liveliness_subscriber",
                "liveliness_query",
            ],
            fleet.all(),
        ),
        rule("ask", "ingress", &["query"], ask_keys),
    ];
    if let Some(ros2) = fleet.ros2 {
        // What a listening ROS 2 node declares in the graph (its node, its subscriptions), for an
        // observer or a recorder: any token but the fleet's own nodes', which say who plays a
        // vehicle.
        let graph = vec![format!("@ros2_lv/{}/**", ros2.domain)];
        rules.push(rule("ros2-graph", "ingress", &["liveliness_token"], graph));
        let mut deny = rule(
            "ros2-not-the-fleet",
            "ingress",
            &["liveliness_token"],
            fleet_nodes(ros2),
        );
        deny["permission"] = json!("deny");
        rules.push(deny);
    }
    let mut subjects = Vec::new();
    let mut policies = Vec::new();
    for identity in identities(fleet) {
        let name = identity.to_string();
        let mut own = vec!["hear".to_string(), "listen".to_string(), "ask".to_string()];
        for (what, messages, keys) in speaks(fleet, identity) {
            let id = format!("{name}-{what}");
            rules.push(rule(&id, "ingress", &messages, keys));
            own.push(id);
        }
        if let (Some(_), Identity::Observer | Identity::Recorder) = (fleet.ros2, identity) {
            own.extend(["ros2-graph".to_string(), "ros2-not-the-fleet".to_string()]);
        }
        let by = match naming {
            Naming::Username => "usernames",
            Naming::CommonName => "cert_common_names",
        };
        subjects.push(json!({ "id": name, by: [name] }));
        policies.push(json!({ "id": name, "subjects": [name], "rules": own }));
    }
    json!({
        "enabled": true,
        "default_permission": "deny",
        "rules": rules,
        "subjects": subjects,
        "policies": policies,
    })
}

/// Lets links with no credential, over `protocol` (the open endpoint of `tcpf run --ros2-open`,
/// where a stock ROS 2 node connects with no configuration), do what an observer does: listen,
/// and declare a listening ROS 2 node in the graph. A link over the fleet's own TLS has a
/// certificate's name and never matches. `acl` is `access_control` of a fleet that speaks ROS 2.
pub fn open_to_listeners(acl: &mut Value, protocol: &str) {
    let observer = rules_of(acl, &Identity::Observer.to_string())
        .unwrap_or(&json!([]))
        .clone();
    if let Some(subjects) = acl["subjects"].as_array_mut() {
        subjects.push(json!({ "id": "open", "link_protocols": [protocol] }));
    }
    if let Some(policies) = acl["policies"].as_array_mut() {
        policies.push(json!({ "id": "open", "subjects": ["open"], "rules": observer }));
    }
}

/// The rules of the policy `id` in `acl`, an `access_control` section.
fn rules_of<'a>(acl: &'a Value, id: &str) -> Option<&'a Value> {
    acl["policies"]
        .as_array()?
        .iter()
        .find(|p| p["id"] == id)
        .map(|p| &p["rules"])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn allowed(acl: &Value, identity: Identity, flow: &str, message: &str) -> Vec<String> {
        let own: Vec<&str> = rules_of(acl, &identity.to_string())
            .unwrap()
            .as_array()
            .unwrap()
            .iter()
            .map(|r| r.as_str().unwrap())
            .collect();
        acl["rules"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|r| own.contains(&r["id"].as_str().unwrap()))
            .filter(|r| r["flows"].as_array().unwrap().iter().any(|f| f == flow))
            .filter(|r| r["messages"].as_array().unwrap().iter().any(|m| m == message))
            .flat_map(|r| {
                r["key_exprs"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|k| k.as_str().unwrap().to_string())
            })
            .collect()
    }

    /// Mission `m` of vehicles 1 and 2, both simulated, speaking ROS 2 as `ros2` says.
    fn two_vehicles(ros2: &Ros2Config) -> Fleet<'_> {
        Fleet {
            keys: Keys::new("m"),
            vehicles: &[1, 2],
            ros2: Some(ros2),
            played: &[],
        }
    }

    #[test]
    fn each_identity_may_publish_only_what_its_role_publishes() {
        let ros2 = Ros2Config::on(7);
        let fleet = two_vehicles(&ros2);
        let acl = access_control(&fleet, Naming::Username);
        let puts = |identity| allowed(&acl, identity, "ingress", "put");
        assert_eq!(
            puts(Identity::Agent(2)),
            ["tcpf/m/cmd/2", "tcpf/m/gamma/2", "7/tcpf/vehicle_2/cmd/**"]
        );
        assert_eq!(puts(Identity::Planner), ["tcpf/m/plan/*"]);
        assert_eq!(puts(Identity::Vehicle(1)), ["7/tcpf/vehicle_1/odom/**"]);
        assert!(puts(Identity::Recorder).is_empty());
        assert!(puts(Identity::Observer).is_empty());
        assert!(puts(Identity::World).contains(&"tcpf/m/**".to_string()));
        assert_eq!(
            allowed(&acl, Identity::Observer, "ingress", "reply"),
            Vec::<String>::new()
        );
        assert_eq!(
            allowed(&acl, Identity::Recorder, "ingress", "reply"),
            ["tcpf/m/report/**", "tcpf/m/end", "tcpf/m/lost/*"]
        );
        assert_eq!(
            allowed(&acl, Identity::Agent(1), "ingress", "query"),
            [
                "tcpf/m/plan/*",
                "tcpf/m/clock",
                "tcpf/m/history",
                "7/tcpf/**/@adv/**",
                "tcpf/m/report/agent/1"
            ]
        );
        // The world alone answers for its history: a recorder may ask, never answer.
        assert!(!allowed(&acl, Identity::Recorder, "ingress", "declare_queryable").contains(&"tcpf/m/history".into()));
        assert_eq!(
            allowed(&acl, Identity::Agent(1), "ingress", "liveliness_token"),
            [
                "tcpf/m/alive/agent/1",
                "tcpf/m/claim/agent/1/*",
                "@ros2_lv/7/*/*/*/*/%/%tcpf/agent_1",
                "@ros2_lv/7/*/*/*/*/%/%tcpf/agent_1/**"
            ]
        );
        // A ROS 2 tool that listens declares its node and subscriptions, never the fleet's nodes.
        let observer = rules_of(&acl, "observer").unwrap();
        assert!(observer.as_array().unwrap().contains(&json!("ros2-not-the-fleet")));
        let deny = acl["rules"]
            .as_array()
            .unwrap()
            .iter()
            .find(|r| r["id"] == "ros2-not-the-fleet")
            .unwrap();
        assert_eq!(deny["permission"], "deny");
        assert!(deny["key_exprs"]
            .as_array()
            .unwrap()
            .contains(&json!("@ros2_lv/7/*/*/*/*/%/%tcpf/vehicle_$*")));
        assert!(
            !allowed(&acl, Identity::Agent(1), "ingress", "liveliness_token").contains(&"@ros2_lv/7/**".to_string())
        );
        // Everyone hears the whole fleet.
        assert_eq!(allowed(&acl, Identity::Observer, "egress", "put"), fleet.all());
        // A fleet whose vehicle 2 another program may play on its own protocol: its player
        // publishes its states, and nothing else; without ROS 2 it has no node, and vehicle 1,
        // which the world simulates, has no player at all.
        let played = Fleet {
            played: &[2],
            ros2: None,
            ..fleet
        };
        let acl = access_control(&played, Naming::Username);
        assert_eq!(
            allowed(&acl, Identity::Vehicle(2), "ingress", "put"),
            ["tcpf/m/state/2"]
        );
        assert!(allowed(&acl, Identity::Vehicle(2), "ingress", "liveliness_token").is_empty());
        assert_eq!(
            identities(&played),
            [
                Identity::World,
                Identity::Planner,
                Identity::Recorder,
                Identity::Observer,
                Identity::Agent(1),
                Identity::Agent(2),
                Identity::Vehicle(2)
            ]
        );
    }

    #[test]
    fn an_open_link_may_do_what_an_observer_does() {
        let ros2 = Ros2Config::on(7);
        let fleet = two_vehicles(&ros2);
        let mut acl = access_control(&fleet, Naming::CommonName);
        open_to_listeners(&mut acl, "tcp");
        assert_eq!(rules_of(&acl, "open").unwrap(), rules_of(&acl, "observer").unwrap());
        let open = acl["subjects"]
            .as_array()
            .unwrap()
            .iter()
            .find(|s| s["id"] == "open")
            .unwrap();
        assert_eq!(open, &json!({ "id": "open", "link_protocols": ["tcp"] }));
        let mut config = zenoh::Config::default();
        config.insert_json5("access_control", &acl.to_string()).unwrap();
    }

    #[test]
    fn zenoh_takes_the_rules() {
        let fleet = Fleet {
            keys: Keys::new("*"),
            vehicles: &[1, 2, 3],
            ros2: None,
            played: &[1, 2, 3],
        };
        let mut config = zenoh::Config::default();
        config
            .insert_json5(
                "access_control",
                &access_control(&fleet, Naming::CommonName).to_string(),
            )
            .unwrap();
        assert_eq!(
            config.get_json("access_control/default_permission").unwrap(),
            "\"deny\""
        );
    }
}
