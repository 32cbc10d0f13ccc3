//! A simulated chain of Dynamixel X-series servos on a pseudo-terminal, for tests.
//!
//! [`ServoChain::spawn_on_pty`] opens a pty pair, puts it in raw mode, runs the chain on the
//! master end in a thread named `servo-sim`, and hands back the slave end as a [`SerialPort`] for
//! the driver. The servos answer PING, READ, WRITE, SYNC READ and SYNC WRITE with real
//! Protocol 2.0 status packets (CRC, stuffing, error byte); instruction packets with a bad CRC
//! are ignored, as real servos do.
//!
//! Each servo has a 147-byte X-series control table (model number 1020 = XM430-W350, firmware
//! 45). With torque on, Present Position moves towards Goal Position at Profile Velocity
//! (0.229 rev/min per unit; 0 = at once), using the thread's wall clock.
//!
//! Faults: each status packet is independently dropped (never sent) with probability `drop`, or
//! sent with a corrupted CRC with probability `corrupt`, from a seeded generator; the chain
//! counts what it did ([`ChainCounters`]) so tests can hold the driver's counts against it.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{Read, Write};
use std::os::fd::OwnedFd;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crate::dynamixel::protocol::{BROADCAST_ID, Decoded, Instruction, Packet, decode};
use crate::dynamixel::reg;
use crate::dynamixel::transport::{SerialPort, set_raw, wait_readable};

/// Size of the simulated control table (bytes), up to Present Temperature (146).
pub const TABLE_SIZE: usize = 147;
/// Model number reported by PING (XM430-W350).
pub const MODEL_NUMBER: u16 = 1020;
/// Firmware version reported by PING.
pub const FIRMWARE: u8 = 45;
const ADDR_FIRMWARE: usize = 6;
const ADDR_ID: usize = 7;

/// Fault injection: probabilities per status packet, in `[0, 1]`, `drop + corrupt ≤ 1`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Faults {
    pub drop: f64,
    pub corrupt: f64,
}

/// What the chain has done so far.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ChainCounters {
    /// Valid instruction packets received.
    pub instructions: u64,
    /// Instruction bytes that did not decode (bad CRC, junk).
    pub bad_instructions: u64,
    /// Status packets sent intact.
    pub replies: u64,
    /// Status packets not sent (fault).
    pub dropped: u64,
    /// Status packets sent with a corrupted CRC (fault).
    pub corrupted: u64,
}

#[derive(Default)]
struct Counters {
    instructions: AtomicU64,
    bad_instructions: AtomicU64,
    replies: AtomicU64,
    dropped: AtomicU64,
    corrupted: AtomicU64,
}

struct Servo {
    table: Vec<u8>,
    /// Sub-tick remainder of the motion (ticks).
    carry: f64,
}

impl Servo {
    fn new(id: u8) -> Self {
        let mut table = vec![0u8; TABLE_SIZE];
        table[0..2].copy_from_slice(&MODEL_NUMBER.to_le_bytes());
        table[ADDR_FIRMWARE] = FIRMWARE;
        table[ADDR_ID] = id;
        let center = 2048i32.to_le_bytes();
        table[116..120].copy_from_slice(&center);
        table[132..136].copy_from_slice(&center);
        Self { table, carry: 0.0 }
    }

    fn get_i32(&self, addr: u16) -> i32 {
        let a = usize::from(addr);
        i32::from_le_bytes([
            self.table[a],
            self.table[a + 1],
            self.table[a + 2],
            self.table[a + 3],
        ])
    }

    fn set_i32(&mut self, addr: u16, v: i32) {
        let a = usize::from(addr);
        self.table[a..a + 4].copy_from_slice(&v.to_le_bytes());
    }

    /// Moves Present Position towards Goal Position for `dt_s` seconds.
    fn advance(&mut self, dt_s: f64) {
        if self.table[usize::from(reg::TORQUE_ENABLE)] == 0 {
            return;
        }
        let goal = self.get_i32(reg::GOAL_POSITION);
        let present = self.get_i32(reg::PRESENT_POSITION);
        let profile = self.get_i32(reg::PROFILE_VELOCITY);
        if profile == 0 {
            self.set_i32(reg::PRESENT_POSITION, goal);
            return;
        }
        let ticks_per_s = f64::from(profile) * 0.229 / 60.0 * 4096.0;
        self.carry += ticks_per_s * dt_s;
        let step = self.carry.floor();
        self.carry -= step;
        let step = step as i64;
        let diff = i64::from(goal) - i64::from(present);
        let moved = diff.clamp(-step, step);
        self.set_i32(reg::PRESENT_POSITION, present + moved as i32);
        if moved == diff {
            self.carry = 0.0;
        }
    }
}

struct Shared {
    servos: Mutex<BTreeMap<u8, Servo>>,
    faults: Mutex<Faults>,
    counters: Counters,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// A running simulated servo chain; stops its thread when dropped.
pub struct ServoChain {
    shared: Arc<Shared>,
    stop: Arc<AtomicBool>,
    handle: Option<JoinHandle<()>>,
    /// The line's far end, held open for a driver that opens it by path.
    _slave: Option<std::os::fd::OwnedFd>,
}

impl std::fmt::Debug for ServoChain {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ServoChain")
            .field("counters", &self.counters())
            .finish()
    }
}

/// SplitMix64: a small, seeded, deterministic generator (no dependency).
struct SplitMix(u64);

impl SplitMix {
    fn next_f64(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }
}

impl ServoChain {
    /// Servos `ids` on a new pty; returns the chain and the driver's end of the line.
    pub fn spawn_on_pty(
        ids: &[u8],
        faults: Faults,
        seed: u64,
    ) -> std::io::Result<(Self, SerialPort)> {
        let (chain, slave) = Self::spawn(ids, faults, seed)?;
        Ok((chain, SerialPort::from_fd(slave, None)?))
    }

    /// Servos `ids` on a new pty; returns the chain and the path of the line's far end, for a
    /// driver that opens it by name (`joint_motor --driver dynamixel --port <path>`).
    pub fn spawn_on_pty_path(
        ids: &[u8],
        faults: Faults,
        seed: u64,
    ) -> std::io::Result<(Self, std::path::PathBuf)> {
        let (mut chain, slave) = Self::spawn(ids, faults, seed)?;
        let path = nix::unistd::ttyname(&slave)?;
        chain._slave = Some(slave);
        Ok((chain, path))
    }

    fn spawn(
        ids: &[u8],
        faults: Faults,
        seed: u64,
    ) -> std::io::Result<(Self, std::os::fd::OwnedFd)> {
        let pty = nix::pty::openpty(None, None)?;
        set_raw(&pty.slave, None)?;
        let shared = Arc::new(Shared {
            servos: Mutex::new(ids.iter().map(|&id| (id, Servo::new(id))).collect()),
            faults: Mutex::new(faults),
            counters: Counters::default(),
        });
        let stop = Arc::new(AtomicBool::new(false));
        let handle = std::thread::Builder::new()
            .name("servo-sim".into())
            .spawn({
                let shared = Arc::clone(&shared);
                let stop = Arc::clone(&stop);
                move || run(pty.master, &shared, &stop, SplitMix(seed))
            })?;
        Ok((
            Self {
                shared,
                stop,
                handle: Some(handle),
                _slave: None,
            },
            pty.slave,
        ))
    }

    /// Changes the fault probabilities.
    pub fn set_faults(&self, faults: Faults) {
        *lock(&self.shared.faults) = faults;
    }

    /// The counters so far.
    pub fn counters(&self) -> ChainCounters {
        let c = &self.shared.counters;
        ChainCounters {
            instructions: c.instructions.load(Ordering::SeqCst),
            bad_instructions: c.bad_instructions.load(Ordering::SeqCst),
            replies: c.replies.load(Ordering::SeqCst),
            dropped: c.dropped.load(Ordering::SeqCst),
            corrupted: c.corrupted.load(Ordering::SeqCst),
        }
    }

    /// A 4-byte register of servo `id` (e.g. [`reg::GOAL_POSITION`]).
    pub fn register(&self, id: u8, addr: u16) -> Option<i32> {
        lock(&self.shared.servos).get(&id).map(|s| s.get_i32(addr))
    }

    /// Sets a 4-byte register of servo `id` (e.g. to place Present Position).
    pub fn set_register(&self, id: u8, addr: u16, value: i32) {
        if let Some(s) = lock(&self.shared.servos).get_mut(&id) {
            s.set_i32(addr, value);
        }
    }

    /// Whether servo `id` has torque on.
    pub fn torque(&self, id: u8) -> Option<bool> {
        lock(&self.shared.servos)
            .get(&id)
            .map(|s| s.table[usize::from(reg::TORQUE_ENABLE)] != 0)
    }
}

impl Drop for ServoChain {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(h) = self.handle.take() {
            let _ = h.join();
        }
    }
}

#[expect(
    clippy::disallowed_methods,
    reason = "the simulated servo chain's device thread behind a pseudo-terminal: servos move in \
              real time, as the serial line they answer on runs"
)]
fn run(master: OwnedFd, shared: &Shared, stop: &AtomicBool, mut rng: SplitMix) {
    let mut file = File::from(master);
    let mut rx: Vec<u8> = Vec::new();
    let mut last = Instant::now();
    while !stop.load(Ordering::SeqCst) {
        let now = Instant::now();
        let dt = now.duration_since(last).as_secs_f64();
        last = now;
        for s in lock(&shared.servos).values_mut() {
            s.advance(dt);
        }
        match wait_readable(&file, Duration::from_millis(5)) {
            Ok(true) => {}
            Ok(false) => continue,
            Err(_) => break,
        }
        let mut buf = [0u8; 512];
        match file.read(&mut buf) {
            Ok(0) => {
                // The driver's end is closed (EOF/hang-up): wait for the stop flag.
                std::thread::sleep(Duration::from_millis(5));
                continue;
            }
            Ok(n) => rx.extend_from_slice(&buf[..n]),
            Err(_) => {
                std::thread::sleep(Duration::from_millis(5));
                continue;
            }
        }
        loop {
            match decode(&rx) {
                Decoded::Packet { packet, consumed } => {
                    rx.drain(..consumed);
                    shared.counters.instructions.fetch_add(1, Ordering::SeqCst);
                    let replies = handle(shared, &packet);
                    let out = faulty(shared, &mut rng, replies);
                    if !out.is_empty() && file.write_all(&out).is_err() {
                        break;
                    }
                }
                Decoded::Invalid { consumed, .. } => {
                    rx.drain(..consumed);
                    shared
                        .counters
                        .bad_instructions
                        .fetch_add(1, Ordering::SeqCst);
                }
                Decoded::NeedMore => break,
            }
        }
    }
}

/// Applies the fault draws to the status packets and concatenates what is sent.
fn faulty(shared: &Shared, rng: &mut SplitMix, replies: Vec<Packet>) -> Vec<u8> {
    let faults = *lock(&shared.faults);
    let c = &shared.counters;
    let mut out = Vec::new();
    for p in replies {
        let r = rng.next_f64();
        let mut bytes = p.encode();
        if r < faults.drop {
            c.dropped.fetch_add(1, Ordering::SeqCst);
            continue;
        }
        if r < faults.drop + faults.corrupt {
            if let Some(last) = bytes.last_mut() {
                *last ^= 0x5A;
            }
            c.corrupted.fetch_add(1, Ordering::SeqCst);
        } else {
            c.replies.fetch_add(1, Ordering::SeqCst);
        }
        out.extend_from_slice(&bytes);
    }
    out
}

fn status(id: u8, error: u8, data: &[u8]) -> Packet {
    let mut params = vec![error];
    params.extend_from_slice(data);
    Packet::new(id, Instruction::Status, params)
}

/// Error numbers of the status error byte.
const ERR_INSTRUCTION: u8 = 2;
const ERR_DATA_LENGTH: u8 = 5;
const ERR_ACCESS: u8 = 7;

fn u16_at(p: &[u8], i: usize) -> Option<u16> {
    Some(u16::from_le_bytes([*p.get(i)?, *p.get(i + 1)?]))
}

fn read_table(servo: &Servo, addr: u16, len: u16) -> Result<Vec<u8>, u8> {
    let (a, n) = (usize::from(addr), usize::from(len));
    servo
        .table
        .get(a..a + n)
        .map(<[u8]>::to_vec)
        .ok_or(ERR_ACCESS)
}

fn write_table(servo: &mut Servo, addr: u16, data: &[u8]) -> Result<(), u8> {
    let a = usize::from(addr);
    let slot = servo.table.get_mut(a..a + data.len()).ok_or(ERR_ACCESS)?;
    slot.copy_from_slice(data);
    Ok(())
}

/// The status packets a chain of real X-series servos would send for `p`.
fn handle(shared: &Shared, p: &Packet) -> Vec<Packet> {
    let mut servos = lock(&shared.servos);
    let broadcast = p.id == BROADCAST_ID;
    match Instruction::from_code(p.instruction) {
        Some(Instruction::Ping) => servos
            .iter()
            .filter(|(id, _)| broadcast || **id == p.id)
            .map(|(id, s)| status(*id, 0, &[s.table[0], s.table[1], s.table[ADDR_FIRMWARE]]))
            .collect(),
        Some(Instruction::Read) if !broadcast => {
            let Some(s) = servos.get(&p.id) else {
                return vec![];
            };
            match (u16_at(&p.params, 0), u16_at(&p.params, 2)) {
                (Some(addr), Some(len)) if p.params.len() == 4 => match read_table(s, addr, len) {
                    Ok(d) => vec![status(p.id, 0, &d)],
                    Err(e) => vec![status(p.id, e, &[])],
                },
                _ => vec![status(p.id, ERR_DATA_LENGTH, &[])],
            }
        }
        Some(Instruction::Write) => {
            let Some(addr) = u16_at(&p.params, 0) else {
                return vec![];
            };
            let data = &p.params[2..];
            let mut out = vec![];
            for (id, s) in servos
                .iter_mut()
                .filter(|(id, _)| broadcast || **id == p.id)
            {
                let err = write_table(s, addr, data).err().unwrap_or(0);
                if !broadcast {
                    out.push(status(*id, err, &[]));
                }
            }
            out
        }
        Some(Instruction::SyncRead) if broadcast => {
            let (Some(addr), Some(len)) = (u16_at(&p.params, 0), u16_at(&p.params, 2)) else {
                return vec![];
            };
            p.params[4..]
                .iter()
                .filter_map(|id| servos.get(id).map(|s| (*id, s)))
                .map(|(id, s)| match read_table(s, addr, len) {
                    Ok(d) => status(id, 0, &d),
                    Err(e) => status(id, e, &[]),
                })
                .collect()
        }
        Some(Instruction::SyncWrite) if broadcast => {
            let (Some(addr), Some(len)) = (u16_at(&p.params, 0), u16_at(&p.params, 2)) else {
                return vec![];
            };
            for item in p.params[4..].chunks(usize::from(len) + 1) {
                if item.len() == usize::from(len) + 1
                    && let Some(s) = servos.get_mut(&item[0])
                {
                    let _ = write_table(s, addr, &item[1..]);
                }
            }
            vec![]
        }
        _ if broadcast => vec![],
        _ => {
            if servos.contains_key(&p.id) {
                vec![status(p.id, ERR_INSTRUCTION, &[])]
            } else {
                vec![]
            }
        }
    }
}
