//! Several machines on one host: network namespaces joined by veth pairs through a switch (a
//! bridge in a namespace of its own), for the tests of graphs over several machines. Needs root
//! (CAP_NET_ADMIN), as CI has. Traffic never leaves the host.
//!
//! Links can be made slow and lossy ([`Net::impair`]).
//!
//! Machine `i` is the namespace `<name>-m<i>` with `eth0` at `10.88.0.<i+1>/24` and its own
//! loopback; the switch is `<name>-sw`. Everything is deleted when the [`Net`] is dropped (a
//! test that panics too), and namespaces that a dead test process left are deleted by the next.

use crate::Lines;
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicU32, Ordering};

const PREFIX: &str = "rct";

/// Machines as network namespaces on one switch.
pub struct Net {
    name: String,
    machines: usize,
    /// Processes of the network itself (the delay lines).
    helpers: Vec<Proc>,
}

fn ip(args: &[&str]) {
    let out = Command::new("ip")
        .args(args)
        .output()
        .expect("run ip(8) (iproute2)");
    assert!(
        out.status.success(),
        "ip {} failed (network namespaces need root): {}",
        args.join(" "),
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Delete the namespaces a test process that is gone left behind.
fn prune() {
    let Ok(out) = Command::new("ip").args(["netns", "list"]).output() else {
        return;
    };
    for line in String::from_utf8_lossy(&out.stdout).lines() {
        let ns = line.split_whitespace().next().unwrap_or("");
        let mut parts = ns.split('-');
        if parts.next() != Some(PREFIX) {
            continue;
        }
        let Some(pid) = parts.next().and_then(|p| p.parse::<u32>().ok()) else {
            continue;
        };
        if !crate::alive(pid) {
            kill_inside(ns);
            let _ = Command::new("ip").args(["netns", "del", ns]).status();
        }
    }
}

fn kill_inside(ns: &str) {
    if let Ok(out) = Command::new("ip").args(["netns", "pids", ns]).output() {
        for pid in String::from_utf8_lossy(&out.stdout).split_whitespace() {
            crate::signal(pid.parse().unwrap_or(0), "KILL");
        }
    }
}

impl Net {
    /// `machines` machines on one switch.
    pub fn new(machines: usize) -> Net {
        static N: AtomicU32 = AtomicU32::new(0);
        static PRUNED: std::sync::Once = std::sync::Once::new();
        PRUNED.call_once(prune);
        let n = N.fetch_add(1, Ordering::Relaxed);
        let name = format!("{PREFIX}-{}-{n}", std::process::id());
        let net = Net {
            name,
            machines: 0,
            helpers: Vec::new(),
        };
        let sw = net.switch();
        ip(&["netns", "add", &sw]);
        let mut net = net;
        ip(&["-n", &sw, "link", "add", "br0", "type", "bridge"]);
        ip(&["-n", &sw, "link", "set", "br0", "up"]);
        for i in 0..machines {
            let ns = net.ns(i);
            ip(&["netns", "add", &ns]);
            net.machines = i + 1;
            // Unique names while both ends are in this namespace, renamed once moved.
            let tag = format!("rcv{}{}", std::process::id() % 10_000, n % 10);
            let (a, b) = (format!("{tag}a{i}"), format!("{tag}b{i}"));
            ip(&["link", "add", &a, "type", "veth", "peer", "name", &b]);
            ip(&["link", "set", &a, "netns", &ns]);
            ip(&["link", "set", &b, "netns", &sw]);
            ip(&["-n", &ns, "link", "set", &a, "name", "eth0"]);
            ip(&["-n", &sw, "link", "set", &b, "name", &format!("port{i}")]);
            ip(&[
                "-n",
                &sw,
                "link",
                "set",
                &format!("port{i}"),
                "master",
                "br0",
            ]);
            ip(&["-n", &sw, "link", "set", &format!("port{i}"), "up"]);
            ip(&[
                "-n",
                &ns,
                "addr",
                "add",
                &format!("{}/24", net.ip(i)),
                "dev",
                "eth0",
            ]);
            ip(&["-n", &ns, "link", "set", "eth0", "up"]);
            ip(&["-n", &ns, "link", "set", "lo", "up"]);
        }
        net
    }

    fn switch(&self) -> String {
        format!("{}-sw", self.name)
    }

    /// Machine `i`'s namespace.
    pub fn ns(&self, i: usize) -> String {
        format!("{}-m{i}", self.name)
    }

    /// Machine `i`'s address.
    pub fn ip(&self, i: usize) -> String {
        format!("10.88.0.{}", i + 1)
    }

    /// Machine `i`'s outgoing links made slow and lossy: every TCP connection it opens to
    /// another machine passes through a delay line (`delay_line`, holding each chunk `delay_ms`
    /// each way), and the kernel drops `loss_permille` of every thousand packets it sends. (This
    /// kernel has no `netem`; the delay line is the same thing for TCP streams, and the loss is
    /// real packet loss that TCP retransmits.) Needs nftables.
    pub fn impair(&mut self, i: usize, delay_ms: u64, loss_permille: u32) {
        let ns = self.ns(i);
        let rules = format!(
            "table ip robocog_test {{
  chain divert {{
    type nat hook output priority -100; policy accept;
    oifname \"lo\" return
    meta mark 0x52 return
    ip protocol tcp redirect to :17450
  }}
  chain lossy {{
    type filter hook postrouting priority 0; policy accept;
    oifname != \"lo\" numgen random mod 1000 < {loss_permille} drop
  }}
}}
"
        );
        let mut nft = Command::new("ip")
            .args(["netns", "exec", &ns, "nft", "-f", "-"])
            .stdin(Stdio::piped())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("run nft (Debian's nftables)");
        {
            use std::io::Write;
            let mut stdin = nft.stdin.take().expect("nft stdin");
            stdin.write_all(rules.as_bytes()).expect("write the rules");
        }
        let out = nft.wait_with_output().expect("nft");
        assert!(
            out.status.success(),
            "nft in {ns}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let line = self.spawn(
            i,
            &crate::bin("delay_line"),
            &[
                "--listen".into(),
                "127.0.0.1:17450".into(),
                "--delay-ms".into(),
                delay_ms.to_string(),
            ],
        );
        line.lines
            .wait_for("the delay line", std::time::Duration::from_secs(10), |l| {
                l.starts_with("delay line on")
            });
        self.helpers.push(line);
    }

    /// How many connections the delay lines relayed to machine `i`'s address (so a test knows
    /// its links really went through them).
    pub fn relayed_to(&self, i: usize) -> usize {
        let to = format!("-> {}:", self.ip(i));
        self.helpers
            .iter()
            .map(|h| {
                h.lines
                    .count(|l| l.starts_with("relaying") && l.contains(&to))
            })
            .sum()
    }

    /// Machine `i`'s cable unplugged (`false`) or back (`true`).
    pub fn link(&self, i: usize, up: bool) {
        ip(&[
            "-n",
            &self.ns(i),
            "link",
            "set",
            "eth0",
            if up { "up" } else { "down" },
        ]);
    }

    /// Run `program` on machine `i`, its output collected.
    pub fn spawn(&self, i: usize, program: &std::path::Path, args: &[String]) -> Proc {
        let mut child = Command::new("ip")
            .args(["netns", "exec", &self.ns(i)])
            .arg(program)
            .args(args)
            .env("RUST_LOG", "info")
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("ip netns exec");
        let lines = Lines::default();
        lines.follow(child.stdout.take().expect("stdout"));
        lines.follow(child.stderr.take().expect("stderr"));
        Proc { child, lines }
    }
}

impl Drop for Net {
    fn drop(&mut self) {
        self.helpers.clear();
        let mut all: Vec<String> = (0..self.machines).map(|i| self.ns(i)).collect();
        all.push(self.switch());
        for ns in all {
            kill_inside(&ns);
            let _ = Command::new("ip").args(["netns", "del", &ns]).status();
        }
    }
}

/// A process on one of the machines; killed when dropped.
pub struct Proc {
    pub child: Child,
    pub lines: Lines,
}

impl Proc {
    pub fn sigterm(&self) {
        crate::signal(self.child.id(), "TERM");
    }
    pub fn wait_exit(&mut self, timeout: std::time::Duration) -> std::process::ExitStatus {
        crate::wait_child(&mut self.child, timeout).unwrap_or_else(|| {
            panic!(
                "still running after {timeout:?}; output:\n{}",
                self.lines.all().join("\n")
            )
        })
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        if self.child.try_wait().ok().flatten().is_none() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}
