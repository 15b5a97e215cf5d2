//! Accepting connections for the gRPC server: a failed accept (out of file descriptors)
//! backs off instead of retrying at once, and a connection must make an authenticated call
//! (a worker's Hello, a client's request with the secret) within a deadline or be closed.
//!
//! Without the deadline, 500 connections that never spoke held 500 descriptors forever
//! and starved a process limited to 64 (health and status hung until they went away):
//! they never reach HTTP/2, so neither the secret nor keepalive pings ever touch them; and
//! one that opens HTTP/2 and then idles answers the keepalive pings for ever. The
//! interceptor that checks the secret marks the connection ([`ConnectionInfo`]); from then
//! on, the server's HTTP/2 keepalive (a ping every 10 s, 20 s to answer) closes peers that
//! stop answering. Health needs no secret, so a prober's connection lasts the deadline: it
//! asks on a new one next time.

use std::future::Future;
use std::io;
use std::pin::Pin;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::task::{Context, Poll};
use std::time::Duration;
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::net::{TcpListener, TcpStream};
use tokio::time::{Instant, Sleep};
use tonic::transport::server::{Connected, TcpConnectInfo};

/// The first wait after a failed accept, doubled on each failure in a row up to
/// [`MAX_BACKOFF`] (as tokio-rs/mini-redis's accept loop does).
const FIRST_BACKOFF: Duration = Duration::from_millis(10);
const MAX_BACKOFF: Duration = Duration::from_secs(1);

/// How long to wait after a failed accept: 10 ms, doubled on each failure in a row up to
/// 1 s, back to 10 ms after a success.
#[derive(Debug)]
pub struct AcceptBackoff(Duration);

impl Default for AcceptBackoff {
    fn default() -> Self {
        AcceptBackoff(FIRST_BACKOFF)
    }
}

impl AcceptBackoff {
    /// An accept failed with `e`: the wait before the next (the first of a run is logged).
    pub fn failed(&mut self, e: &io::Error) -> Duration {
        if self.0 == FIRST_BACKOFF {
            tracing::warn!("accepting a connection failed ({e}); retrying with backoff");
        }
        let wait = self.0;
        self.0 = (self.0 * 2).min(MAX_BACKOFF);
        wait
    }

    /// An accept succeeded.
    pub fn succeeded(&mut self) {
        self.0 = FIRST_BACKOFF;
    }
}

/// The connections a listener accepts, as a stream for tonic's `serve_with_incoming`.
pub struct Incoming {
    listener: TcpListener,
    handshake: Duration,
    backoff: AcceptBackoff,
    waiting: Option<Pin<Box<Sleep>>>,
}

impl Incoming {
    /// Accepts on `listener`; each connection must make an authenticated call within
    /// `handshake`.
    pub fn new(listener: TcpListener, handshake: Duration) -> Self {
        Incoming {
            listener,
            handshake,
            backoff: AcceptBackoff::default(),
            waiting: None,
        }
    }
}

impl tokio_stream::Stream for Incoming {
    type Item = io::Result<Guarded>;

    fn poll_next(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<Option<Self::Item>> {
        loop {
            if let Some(sleep) = self.waiting.as_mut() {
                std::task::ready!(sleep.as_mut().poll(cx));
                self.waiting = None;
            }
            match self.listener.poll_accept(cx) {
                Poll::Pending => return Poll::Pending,
                Poll::Ready(Ok((stream, _))) => {
                    self.backoff.succeeded();
                    // Results are small messages each way: no waiting to fill a segment.
                    let _ = stream.set_nodelay(true);
                    let deadline = Instant::now() + self.handshake;
                    return Poll::Ready(Some(Ok(Guarded::new(stream, deadline))));
                }
                Poll::Ready(Err(e)) => {
                    let wait = self.backoff.failed(&e);
                    self.waiting = Some(Box::pin(tokio::time::sleep(wait)));
                }
            }
        }
    }
}

/// What a call knows of its connection: the peer's address, and the mark that lifts the
/// connection's deadline.
#[derive(Clone, Debug)]
pub struct ConnectionInfo {
    /// The TCP peer.
    pub tcp: TcpConnectInfo,
    authenticated: Arc<AtomicBool>,
}

impl ConnectionInfo {
    /// The connection has made an authenticated call: it may stay.
    pub fn mark_authenticated(&self) {
        self.authenticated.store(true, Ordering::Relaxed);
    }
}

/// An accepted connection, closed (reads fail with `TimedOut`) at its deadline unless a
/// call on it was authenticated first.
pub struct Guarded {
    inner: TcpStream,
    authenticated: Arc<AtomicBool>,
    deadline: Pin<Box<Sleep>>,
}

impl Guarded {
    fn new(inner: TcpStream, deadline: Instant) -> Self {
        Guarded {
            inner,
            authenticated: Arc::new(AtomicBool::new(false)),
            deadline: Box::pin(tokio::time::sleep_until(deadline)),
        }
    }
}

impl AsyncRead for Guarded {
    fn poll_read(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<io::Result<()>> {
        let polled = Pin::new(&mut self.inner).poll_read(cx, buf);
        if self.authenticated.load(Ordering::Relaxed) {
            return polled;
        }
        match polled {
            Poll::Pending if self.deadline.as_mut().poll(cx).is_ready() => Poll::Ready(Err(
                io::Error::new(io::ErrorKind::TimedOut, "no authenticated call in time"),
            )),
            other => other,
        }
    }
}

impl AsyncWrite for Guarded {
    fn poll_write(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<io::Result<usize>> {
        Pin::new(&mut self.inner).poll_write(cx, buf)
    }

    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.inner).poll_flush(cx)
    }

    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.inner).poll_shutdown(cx)
    }

    fn poll_write_vectored(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bufs: &[io::IoSlice<'_>],
    ) -> Poll<io::Result<usize>> {
        Pin::new(&mut self.inner).poll_write_vectored(cx, bufs)
    }

    fn is_write_vectored(&self) -> bool {
        self.inner.is_write_vectored()
    }
}

impl Connected for Guarded {
    type ConnectInfo = ConnectionInfo;

    fn connect_info(&self) -> ConnectionInfo {
        ConnectionInfo {
            tcp: self.inner.connect_info(),
            authenticated: self.authenticated.clone(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    use tokio_stream::StreamExt;

    #[test]
    fn failed_accepts_back_off_to_a_second_and_a_success_starts_over() {
        let mut b = AcceptBackoff::default();
        let e = io::Error::other("too many open files");
        let waits: Vec<u128> = (0..9).map(|_| b.failed(&e).as_millis()).collect();
        assert_eq!(waits, [10, 20, 40, 80, 160, 320, 640, 1000, 1000]);
        b.succeeded();
        assert_eq!(b.failed(&e), FIRST_BACKOFF);
    }

    async fn pair(handshake: Duration) -> (TcpStream, Guarded) {
        let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
        let addr = listener.local_addr().unwrap();
        let mut incoming = Incoming::new(listener, handshake);
        let client = TcpStream::connect(addr).await.unwrap();
        let server = incoming.next().await.unwrap().unwrap();
        (client, server)
    }

    #[tokio::test(start_paused = true)]
    async fn a_connection_that_sends_nothing_is_closed_at_its_deadline() {
        let (_client, mut server) = pair(Duration::from_secs(10)).await;
        let mut buf = [0u8; 64];
        let e = server.read(&mut buf).await.unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::TimedOut);
    }

    #[tokio::test(start_paused = true)]
    async fn talking_is_not_enough_an_authenticated_call_lifts_the_deadline() {
        // HTTP/2's preface and more, but no authenticated call: closed.
        let (mut client, mut server) = pair(Duration::from_secs(10)).await;
        client.write_all(&[b'P'; 100]).await.unwrap();
        let mut buf = [0u8; 256];
        let mut got = 0;
        while got < 100 {
            got += server.read(&mut buf).await.unwrap();
        }
        let e = server.read(&mut buf).await.unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::TimedOut);

        // Marked by the interceptor: it may then stay quiet past the deadline.
        let (_client, mut server) = pair(Duration::from_secs(10)).await;
        server.connect_info().mark_authenticated();
        let quiet = tokio::time::timeout(Duration::from_secs(60), server.read(&mut buf)).await;
        assert!(
            quiet.is_err(),
            "an authenticated connection was closed: {quiet:?}"
        );
    }
}
