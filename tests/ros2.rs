//! ROS 2 as rmw_zenoh speaks it, read by an implementation that is not tcpf's: a Python tool with
//! eclipse-zenoh and rosbags (ROS 2's type hashes and CDR) watches a lockstep run with `--ros2`.

mod common;

use std::collections::BTreeMap;
use std::process::Command;
use std::time::Duration;

use common::{assert_same_run, fleet, paper, run_in_process, scratch, Launch};
use serde_json::Value;

/// A telemetry row's numbers as written, by column name.
fn telemetry(dir: &std::path::Path) -> Vec<BTreeMap<String, String>> {
    let text = std::fs::read_to_string(dir.join("telemetry.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<String> = lines.next().unwrap().split(',').map(str::to_string).collect();
    lines
        .map(|l| header.iter().cloned().zip(l.split(',').map(str::to_string)).collect())
        .collect()
}

fn num(v: &Value) -> f64 {
    v.as_str().map_or_else(|| v.as_f64().unwrap(), |s| s.parse().unwrap())
}

#[test]
fn a_lockstep_run_speaks_rmw_zenoh_that_rosbags_decodes_as_the_telemetry() {
    let _fleet = fleet();
    let dir = scratch("ros2");
    let out = dir.join("run");
    let mut launch = Launch::start(&paper("b-current"), &out, &["--ros2", "0", "--recorders", "1"]);
    launch.wait_for("endpoint", "tcp/");
    let watched = dir.join("ros2.json");
    let script = format!("{}/tests/ros2/watch.py", env!("CARGO_MANIFEST_DIR"));
    let o = Command::new("python3")
        .arg(&script)
        .arg(out.join("zenoh.json5"))
        .args(["paper-b-current", "0"])
        .arg(&watched)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", common::text(&o));
    assert!(launch.wait(Duration::from_secs(60)).success());
    let seen: Value = serde_json::from_str(&std::fs::read_to_string(&watched).unwrap()).unwrap();
    assert_eq!(seen["problems"], serde_json::json!([]), "{}", seen["problems"]);

    // Every key carries the hash rosbags computes for its type, and rmw_zenoh's type name.
    let keys: Vec<&str> = seen["keys"]
        .as_array()
        .unwrap()
        .iter()
        .map(|k| k.as_str().unwrap())
        .collect();
    let odometry_hash = seen["hashes"]["nav_msgs/msg/Odometry"].as_str().unwrap();
    let clock_hash = seen["hashes"]["rosgraph_msgs/msg/Clock"].as_str().unwrap();
    let vector_hash = seen["hashes"]["geometry_msgs/msg/Vector3Stamped"].as_str().unwrap();
    let vector = |topic: &str| format!("0/tcpf/{topic}/geometry_msgs::msg::dds_::Vector3Stamped_/{vector_hash}");
    assert_eq!(
        keys,
        [
            format!("0/clock/rosgraph_msgs::msg::dds_::Clock_/{clock_hash}"),
            vector("coordination"),
            vector("vehicle_1/gamma"),
            format!("0/tcpf/vehicle_1/odom/nav_msgs::msg::dds_::Odometry_/{odometry_hash}"),
            vector("vehicle_2/gamma"),
            format!("0/tcpf/vehicle_2/odom/nav_msgs::msg::dds_::Odometry_/{odometry_hash}"),
        ]
    );

    // The graph: the node /tcpf/world, and one publisher per topic.
    let tokens: Vec<&str> = seen["tokens"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| t.as_str().unwrap())
        .collect();
    let kinds = |kind: &str| tokens.iter().filter(|t| t.split('/').nth(5) == Some(kind)).count();
    assert_eq!((kinds("NN"), kinds("MP"), tokens.len()), (1, 6, 7), "{tokens:?}");
    assert!(tokens.iter().any(|t| t.ends_with("/NN/%/%tcpf/world")), "{tokens:?}");
    for topic in [
        "%clock",
        "%tcpf%vehicle_1%odom",
        "%tcpf%vehicle_2%odom",
        "%tcpf%vehicle_1%gamma",
        "%tcpf%vehicle_2%gamma",
        "%tcpf%coordination",
    ] {
        assert!(
            tokens
                .iter()
                .any(|t| t.contains(&format!("/MP/%/%tcpf/world/{topic}/"))),
            "{topic}: {tokens:?}"
        );
    }

    // Row by row, the poses are the telemetry's, to the float.
    let rows = telemetry(&out);
    for id in ["1", "2"] {
        let mine: Vec<&BTreeMap<String, String>> = rows.iter().filter(|r| r["id"] == id).collect();
        let odometry = seen["odometry"][&format!("vehicle_{id}")].as_array().unwrap();
        assert_eq!(odometry.len(), mine.len(), "vehicle {id}");
        for (o, row) in odometry.iter().zip(&mine) {
            let f = |k: &str| row[k].parse::<f64>().unwrap();
            assert_eq!(
                (num(&o["x"]), num(&o["y"])),
                (f("x"), f("y")),
                "vehicle {id}, tick {}",
                row["tick"]
            );
            let yaw = (num(&o["yaw"]) - f("heading") + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
                - std::f64::consts::PI;
            assert!(
                yaw.abs() < 1e-12,
                "vehicle {id}, tick {}: yaw off by {yaw}",
                row["tick"]
            );
            assert_eq!(num(&o["yaw_rate"]), f("r"), "vehicle {id}, tick {}", row["tick"]);
            let stamp = &o["stamp"];
            let t = stamp[0].as_f64().unwrap() + stamp[1].as_f64().unwrap() * 1e-9;
            assert!((t - f("t")).abs() < 1e-9, "stamp {stamp} at t = {}", row["t"]);
            assert_eq!(
                (o["frame"].as_str(), o["child"].as_str()),
                (Some("map"), Some(&*format!("vehicle_{id}")))
            );
            assert_eq!(o["tilt"], serde_json::json!([0.0, 0.0, 0.0]));
        }
    }

    // γ, γ̇ and γ − t of each vehicle, tick by tick: its γ is the telemetry's, to the bit.
    for id in ["1", "2"] {
        let mine: Vec<&BTreeMap<String, String>> = rows.iter().filter(|r| r["id"] == id).collect();
        let gamma = seen["vectors"][&format!("vehicle_{id}/gamma")].as_array().unwrap();
        assert_eq!(gamma.len(), mine.len(), "vehicle {id}");
        for (v, row) in gamma.iter().zip(&mine) {
            let f = |k: &str| row[k].parse::<f64>().unwrap();
            assert_eq!(num(&v["x"]), f("gamma"), "vehicle {id}, tick {}", row["tick"]);
            assert_eq!(num(&v["z"]), f("gamma") - f("t"), "vehicle {id}, tick {}", row["tick"]);
            assert!(num(&v["y"]) > 0.0, "γ̇ > 0 at tick {}", row["tick"]);
            assert_eq!(v["frame"].as_str(), Some(&*format!("vehicle_{id}")));
        }
    }
    // The fleet's: the coordination error and the distance between the two, from the telemetry.
    let coordination = seen["vectors"]["coordination"].as_array().unwrap();
    let (one, two): (Vec<_>, Vec<_>) = rows.iter().partition(|r| r["id"] == "1");
    assert_eq!(coordination.len(), one.len());
    for ((c, a), b) in coordination.iter().zip(&one).zip(&two) {
        let f = |r: &BTreeMap<String, String>, k: &str| r[k].parse::<f64>().unwrap();
        assert_eq!(
            num(&c["x"]),
            (f(a, "gamma") - f(b, "gamma")).abs(),
            "tick {}",
            a["tick"]
        );
        let apart = (f(a, "x") - f(b, "x")).hypot(f(a, "y") - f(b, "y"));
        assert_eq!(num(&c["y"]), apart, "tick {}", a["tick"]);
        assert_eq!(c["frame"].as_str(), Some("map"));
    }

    // /clock: the fleet's simulated time, tick by tick.
    let clock = seen["clock"].as_array().unwrap();
    let ticks = rows.iter().filter(|r| r["id"] == "1").count();
    assert_eq!(clock.len(), ticks);
    for (k, c) in clock.iter().enumerate() {
        let ns = c[0].as_i64().unwrap() * 1_000_000_000 + c[1].as_i64().unwrap();
        assert_eq!(ns, k as i64 * 10_000_000, "tick {k}");
    }

    // Speaking ROS 2 changes nothing of the run.
    run_in_process(&paper("b-current"), &dir.join("i"), &[]);
    assert_same_run(&out, &dir.join("i"));
}
