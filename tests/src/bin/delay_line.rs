//! A delay line for the tests of graphs over several machines, where the kernel has no `netem`:
//! every TCP connection a machine opens to another machine's router is redirected here (an
//! nftables `redirect` in the machine's namespace), and this relay connects to where it was
//! going (`SO_ORIGINAL_DST`) and passes the bytes on both ways, each chunk held `--delay-ms`
//! first. Its own connections carry a firewall mark so they are not redirected again. Packet
//! loss is the kernel's (an nftables rule dropping a share of the machine's packets), so TCP
//! retransmits as it would on a lossy network.
#![expect(
    clippy::disallowed_methods,
    reason = "the delay line delays real packets by wall-clock time"
)]

use clap::Parser;
use std::net::SocketAddr;
use std::os::fd::AsFd;
use std::time::Duration;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpSocket, TcpStream};
use tokio::sync::mpsc;
use tokio::time::Instant;

#[derive(Debug, Parser)]
#[command(about = "Relay redirected TCP connections to their original destination, late")]
struct Args {
    /// Where the redirected connections arrive.
    #[arg(long, default_value = "127.0.0.1:17450")]
    listen: SocketAddr,
    /// How long every chunk is held, each way (ms).
    #[arg(long, default_value_t = 20)]
    delay_ms: u64,
    /// The firewall mark of the relay's own connections (the redirect rule skips them).
    #[arg(long, default_value_t = 0x52)]
    mark: u32,
}

#[tokio::main(flavor = "current_thread")]
async fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    let listener = TcpListener::bind(args.listen).await?;
    eprintln!(
        "delay line on {}: {} ms each way",
        args.listen, args.delay_ms
    );
    let delay = Duration::from_millis(args.delay_ms);
    loop {
        let (inbound, from) = listener.accept().await?;
        let mark = args.mark;
        tokio::spawn(async move {
            if let Err(e) = relay(inbound, delay, mark).await {
                eprintln!("connection from {from}: {e:#}");
            }
        });
    }
}

async fn relay(inbound: TcpStream, delay: Duration, mark: u32) -> anyhow::Result<()> {
    let dst =
        nix::sys::socket::getsockopt(&inbound.as_fd(), nix::sys::socket::sockopt::OriginalDst)?;
    let dst = SocketAddr::from((
        std::net::Ipv4Addr::from(u32::from_be(dst.sin_addr.s_addr)),
        u16::from_be(dst.sin_port),
    ));
    let socket = TcpSocket::new_v4()?;
    nix::sys::socket::setsockopt(&socket.as_fd(), nix::sys::socket::sockopt::Mark, &mark)?;
    let outbound = socket.connect(dst).await?;
    eprintln!("relaying {} -> {dst}", inbound.peer_addr()?);
    inbound.set_nodelay(true)?;
    outbound.set_nodelay(true)?;
    let (ir, iw) = inbound.into_split();
    let (or, ow) = outbound.into_split();
    let a = tokio::spawn(pump(ir, ow, delay));
    let b = tokio::spawn(pump(or, iw, delay));
    let _ = tokio::join!(a, b);
    Ok(())
}

/// Read chunks from `from`, write each to `to` once `delay` has passed since it arrived.
async fn pump(
    mut from: tokio::net::tcp::OwnedReadHalf,
    mut to: tokio::net::tcp::OwnedWriteHalf,
    delay: Duration,
) {
    let (tx, mut rx) = mpsc::channel::<(Instant, Vec<u8>)>(4096);
    let writer = tokio::spawn(async move {
        while let Some((due, chunk)) = rx.recv().await {
            tokio::time::sleep_until(due).await;
            if to.write_all(&chunk).await.is_err() {
                return;
            }
        }
        let _ = to.shutdown().await;
    });
    let mut buf = vec![0u8; 64 * 1024];
    loop {
        match from.read(&mut buf).await {
            Ok(0) | Err(_) => break,
            Ok(n) => {
                if tx
                    .send((Instant::now() + delay, buf[..n].to_vec()))
                    .await
                    .is_err()
                {
                    break;
                }
            }
        }
    }
    drop(tx);
    let _ = writer.await;
}
