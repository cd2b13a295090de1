//! Hosts on one machine: a Linux network namespace per host, each with its own address on one
//! Ethernet segment (a veth pair per host into a bridge that lives in a namespace of its own, so
//! the machine's own network is never touched). Needs root and `ip` (iproute2). Everything is
//! removed when the `Testbed` is dropped, also when a test fails; namespaces left by a test
//! process that was killed are removed by the next one.

use std::path::Path;
use std::process::{Child, Command, Stdio};

use super::{descendants, kill};

/// The segment every testbed uses: namespaces keep testbeds apart, so they may share it.
const SUBNET: &str = "10.77.0";
const PREFIX: &str = "tcpf-tb";

fn ip(args: &[&str]) {
    let out = Command::new("ip").args(args).output().expect("ip (iproute2) runs");
    assert!(
        out.status.success(),
        "ip {}: {}",
        args.join(" "),
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Namespaces of testbeds whose test process is gone.
fn remove_orphans() {
    let Ok(out) = Command::new("ip").args(["netns", "list"]).output() else {
        return;
    };
    for line in String::from_utf8_lossy(&out.stdout).lines() {
        let name = line.split_whitespace().next().unwrap_or("");
        let Some(rest) = name.strip_prefix(&format!("{PREFIX}-")) else {
            continue;
        };
        let pid = rest.split('-').next().and_then(|p| p.parse::<u32>().ok());
        if pid.is_some_and(|p| !Path::new(&format!("/proc/{p}")).exists()) {
            let _ = Command::new("ip").args(["netns", "del", name]).status();
        }
    }
}

pub struct Testbed {
    switch: String,
    hosts: Vec<(String, String)>,
    children: Vec<Child>,
    /// What the processes it starts log (their RUST_LOG), if not their default.
    pub log_filter: Option<String>,
}

impl Testbed {
    /// Hosts named `names`, at 10.77.0.1, 10.77.0.2, … in that order. `tag` tells this
    /// process's testbeds apart.
    pub fn new(tag: &str, names: &[&str]) -> Testbed {
        remove_orphans();
        let base = format!("{PREFIX}-{}-{tag}", std::process::id());
        let switch = format!("{base}-sw");
        ip(&["netns", "add", &switch]);
        let mut bed = Testbed {
            switch: switch.clone(),
            hosts: Vec::new(),
            children: Vec::new(),
            log_filter: None,
        };
        ip(&["-n", &switch, "link", "add", "br0", "type", "bridge"]);
        ip(&["-n", &switch, "link", "set", "br0", "up"]);
        for (k, name) in names.iter().enumerate() {
            let ns = format!("{base}-{name}");
            ip(&["netns", "add", &ns]);
            bed.hosts.push((name.to_string(), ns.clone()));
            let port = format!("p{k}");
            ip(&[
                "-n", &switch, "link", "add", &port, "type", "veth", "peer", "name", "eth0", "netns", &ns,
            ]);
            ip(&["-n", &switch, "link", "set", &port, "master", "br0"]);
            ip(&["-n", &switch, "link", "set", &port, "up"]);
            ip(&[
                "-n",
                &ns,
                "addr",
                "add",
                &format!("{SUBNET}.{}/24", k + 1),
                "dev",
                "eth0",
            ]);
            ip(&["-n", &ns, "link", "set", "eth0", "up"]);
            ip(&["-n", &ns, "link", "set", "lo", "up"]);
        }
        bed
    }

    fn index(&self, host: &str) -> usize {
        self.hosts
            .iter()
            .position(|h| h.0 == host)
            .unwrap_or_else(|| panic!("no host {host}"))
    }

    /// The address of `host`.
    pub fn address(&self, host: &str) -> String {
        format!("{SUBNET}.{}", self.index(host) + 1)
    }

    /// Starts `program args` on `host`, in `dir`, its output to `log`; killed when the testbed goes.
    pub fn spawn(&mut self, host: &str, dir: &Path, log: &Path, program: &str, args: &[&str]) -> u32 {
        let ns = self.hosts[self.index(host)].1.clone();
        let out = std::fs::File::create(log).unwrap();
        let mut command = Command::new("ip");
        if let Some(filter) = &self.log_filter {
            command.env("RUST_LOG", filter);
        }
        let child = command
            .args(["netns", "exec", &ns, program])
            .args(args)
            .current_dir(dir)
            .stdin(Stdio::null())
            .stdout(Stdio::from(out.try_clone().unwrap()))
            .stderr(Stdio::from(out))
            .spawn()
            .expect("ip netns exec runs");
        let pid = child.id();
        self.children.push(child);
        pid
    }

    /// Takes `host`'s link to the segment down or up, as a cable pulled or plugged.
    pub fn link(&self, host: &str, up: bool) {
        let port = format!("p{}", self.index(host));
        ip(&["-n", &self.switch, "link", "set", &port, if up { "up" } else { "down" }]);
    }

    /// Runs `command` on `host` and returns whether it succeeded (iptables rules, probes).
    pub fn run(&self, host: &str, command: &[&str]) -> bool {
        let ns = &self.hosts[self.index(host)].1;
        Command::new("ip")
            .args(["netns", "exec", ns])
            .args(command)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .is_ok_and(|s| s.success())
    }

    /// Waits for the process `pid` started by `spawn` to exit, up to `limit`; its exit status.
    pub fn wait(&mut self, pid: u32, limit: std::time::Duration) -> Option<std::process::ExitStatus> {
        let deadline = std::time::Instant::now() + limit;
        let child = self.children.iter_mut().find(|c| c.id() == pid)?;
        loop {
            if let Ok(Some(status)) = child.try_wait() {
                return Some(status);
            }
            if std::time::Instant::now() >= deadline {
                return None;
            }
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
    }
}

impl Drop for Testbed {
    fn drop(&mut self) {
        for child in &mut self.children {
            for pid in descendants(child.id()) {
                kill("-9", pid);
            }
            let _ = child.kill();
            let _ = child.wait();
        }
        for (_, ns) in &self.hosts {
            let _ = Command::new("ip").args(["netns", "del", ns]).status();
        }
        let _ = Command::new("ip").args(["netns", "del", &self.switch]).status();
    }
}
