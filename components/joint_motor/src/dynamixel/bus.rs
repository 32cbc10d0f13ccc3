//! Transactions on a Dynamixel bus: send an instruction, wait for the status packet(s), retry
//! what went missing or arrived corrupt, count everything in [`LinkStats`].

use std::time::{Duration, Instant};

use crate::dynamixel::protocol::{
    BROADCAST_ID, DecodeError, Decoded, Instruction, Packet, decode, read_params, sync_read_params,
    sync_write_params, write_params,
};
use crate::dynamixel::transport::Transport;
use crate::error::JointError;
use crate::types::LinkStats;

/// A Protocol 2.0 master on one transport.
pub struct Bus {
    transport: Box<dyn Transport>,
    timeout: Duration,
    retries: u32,
    stats: LinkStats,
    rx: Vec<u8>,
}

impl std::fmt::Debug for Bus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Bus")
            .field("timeout", &self.timeout)
            .field("retries", &self.retries)
            .field("stats", &self.stats)
            .finish()
    }
}

impl Bus {
    /// `timeout`: how long to wait for each status packet; `retries`: repeats after a missing or
    /// corrupt reply.
    pub fn new(transport: Box<dyn Transport>, timeout: Duration, retries: u32) -> Self {
        Self {
            transport,
            timeout,
            retries,
            stats: LinkStats::default(),
            rx: Vec::with_capacity(256),
        }
    }

    /// The link counters so far.
    pub fn stats(&self) -> LinkStats {
        self.stats
    }

    fn io(e: std::io::Error) -> JointError {
        JointError::Bus(format!("serial I/O: {e}"))
    }

    fn send(&mut self, packet: &Packet) -> Result<(), JointError> {
        // Late replies to an earlier instruction must not be taken for this one's.
        self.transport.discard_input().map_err(Self::io)?;
        self.rx.clear();
        self.stats.transactions += 1;
        self.transport.write_all(&packet.encode()).map_err(Self::io)
    }

    /// The next valid status packet from an id accepted by `wanted`, waiting at most the timeout;
    /// `None` if none came. Corrupt and unexpected packets are counted and skipped.
    #[expect(
        clippy::disallowed_methods,
        reason = "a serial-line time-out: how long the servos may take to answer on the real bus"
    )]
    fn receive(&mut self, wanted: impl Fn(u8) -> bool) -> Result<Option<Packet>, JointError> {
        let deadline = Instant::now() + self.timeout;
        loop {
            match decode(&self.rx) {
                Decoded::Packet { packet, consumed } => {
                    self.rx.drain(..consumed);
                    if packet.instruction == Instruction::Status as u8
                        && !packet.params.is_empty()
                        && wanted(packet.id)
                    {
                        return Ok(Some(packet));
                    }
                    self.stats.malformed += 1;
                }
                Decoded::Invalid { error, consumed } => {
                    self.rx.drain(..consumed);
                    match error {
                        DecodeError::Crc { .. } => self.stats.crc_errors += 1,
                        _ => self.stats.malformed += 1,
                    }
                    tracing::debug!(%error, "dropped bytes from the servo bus");
                }
                Decoded::NeedMore => {
                    let left = deadline.saturating_duration_since(Instant::now());
                    if left.is_zero() {
                        return Ok(None);
                    }
                    let mut buf = [0u8; 256];
                    let n = self
                        .transport
                        .read_timeout(&mut buf, left)
                        .map_err(Self::io)?;
                    self.rx.extend_from_slice(&buf[..n]);
                }
            }
        }
    }

    /// Checks a status: servo error codes are refusals (not retried); an alert is counted and
    /// logged, the data still used. Returns the data if it has `data_len` bytes (when given).
    fn accept(
        &mut self,
        packet: &Packet,
        data_len: Option<usize>,
    ) -> Result<Option<Vec<u8>>, JointError> {
        let (err, data) = match packet.status() {
            Ok(s) => s,
            Err(_) => {
                self.stats.malformed += 1;
                return Ok(None);
            }
        };
        if err.0 != 0 {
            self.stats.servo_errors += 1;
            if err.code() != 0 {
                return Err(JointError::Bus(format!(
                    "servo id {} refused the instruction: {} (error byte {:#04x})",
                    packet.id,
                    err.describe(),
                    err.0
                )));
            }
            tracing::warn!(id = packet.id, "servo reports a hardware error (alert bit)");
        }
        if data_len.is_some_and(|n| n != data.len()) {
            self.stats.malformed += 1;
            return Ok(None);
        }
        Ok(Some(data.to_vec()))
    }

    /// One instruction to one servo, retried until a valid status comes back.
    fn transact(
        &mut self,
        packet: &Packet,
        data_len: Option<usize>,
    ) -> Result<Vec<u8>, JointError> {
        let id = packet.id;
        for attempt in 0..=self.retries {
            if attempt > 0 {
                self.stats.retries += 1;
                tracing::debug!(id, attempt, "retrying servo instruction");
            }
            self.send(packet)?;
            if let Some(reply) = self.receive(|r| r == id)? {
                if let Some(data) = self.accept(&reply, data_len)? {
                    return Ok(data);
                }
            } else {
                self.stats.missing_replies += 1;
            }
        }
        self.stats.failures += 1;
        Err(JointError::Bus(format!(
            "no valid reply from servo id {id} after {} tries",
            self.retries + 1
        )))
    }

    /// PING: the servo's model number and firmware version.
    pub fn ping(&mut self, id: u8) -> Result<(u16, u8), JointError> {
        let data = self.transact(&Packet::new(id, Instruction::Ping, vec![]), Some(3))?;
        Ok((u16::from_le_bytes([data[0], data[1]]), data[2]))
    }

    /// READ `len` bytes at `address`.
    pub fn read(&mut self, id: u8, address: u16, len: u16) -> Result<Vec<u8>, JointError> {
        let p = Packet::new(id, Instruction::Read, read_params(address, len));
        self.transact(&p, Some(usize::from(len)))
    }

    /// WRITE `data` at `address`, confirmed by the servo's status.
    pub fn write(&mut self, id: u8, address: u16, data: &[u8]) -> Result<(), JointError> {
        let p = Packet::new(id, Instruction::Write, write_params(address, data));
        self.transact(&p, Some(0)).map(|_| ())
    }

    /// SYNC WRITE the same field of several servos (broadcast: no status, so no retry).
    pub fn sync_write(
        &mut self,
        address: u16,
        len: u16,
        items: &[(u8, Vec<u8>)],
    ) -> Result<(), JointError> {
        if items.iter().any(|(_, d)| d.len() != usize::from(len)) {
            return Err(JointError::Bus("sync write items of unequal length".into()));
        }
        let p = Packet::new(
            BROADCAST_ID,
            Instruction::SyncWrite,
            sync_write_params(address, len, items),
        );
        self.send(&p)
    }

    /// SYNC READ the same field of several servos; servos whose reply is missing or corrupt are
    /// then read one by one (with retries). Data in the order of `ids`.
    pub fn sync_read(
        &mut self,
        address: u16,
        len: u16,
        ids: &[u8],
    ) -> Result<Vec<Vec<u8>>, JointError> {
        let p = Packet::new(
            BROADCAST_ID,
            Instruction::SyncRead,
            sync_read_params(address, len, ids),
        );
        self.send(&p)?;
        let mut got: Vec<Option<Vec<u8>>> = vec![None; ids.len()];
        while got.iter().any(Option::is_none) {
            let pending = |id: u8| ids.iter().zip(&got).any(|(&i, g)| i == id && g.is_none());
            let Some(reply) = self.receive(pending)? else {
                break;
            };
            if let Some(data) = self.accept(&reply, Some(usize::from(len)))?
                && let Some(k) = ids.iter().position(|&i| i == reply.id)
            {
                got[k] = Some(data);
            }
        }
        let missing = got.iter().filter(|g| g.is_none()).count() as u64;
        self.stats.missing_replies += missing;
        let mut out = Vec::with_capacity(ids.len());
        for (k, g) in got.into_iter().enumerate() {
            match g {
                Some(d) => out.push(d),
                None => {
                    self.stats.retries += 1;
                    out.push(self.read(ids[k], address, len)?);
                }
            }
        }
        Ok(out)
    }
}
