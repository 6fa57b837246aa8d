//! Ethernet scanners (UTM-30LX-EW, UST family) speak the same SCIP 2.0 over a
//! TCP socket (port 10940 by default); this makes that socket a [`Port`].

use std::io::{self, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::time::Duration;

use super::{Connector, Port};

/// An open TCP link.
pub(crate) struct TcpPort {
    stream: TcpStream,
    name: String,
}

impl Read for TcpPort {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        self.stream.read(buf)
    }
}

impl Write for TcpPort {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.stream.write(buf)
    }
    fn flush(&mut self) -> io::Result<()> {
        self.stream.flush()
    }
}

impl Port for TcpPort {
    fn set_read_timeout(&mut self, timeout: Duration) -> io::Result<()> {
        self.stream
            .set_read_timeout(Some(timeout.max(Duration::from_millis(1))))
    }
    fn discard_input(&mut self) -> io::Result<()> {
        // A socket has no input queue to flush separately: read what is
        // already there without waiting.
        self.stream.set_nonblocking(true)?;
        let mut buf = [0u8; 512];
        let r = loop {
            match self.stream.read(&mut buf) {
                Ok(0) => break Err(io::Error::from(io::ErrorKind::UnexpectedEof)),
                Ok(_) => continue,
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => break Ok(()),
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => break Err(e),
            }
        };
        self.stream.set_nonblocking(false)?;
        r
    }
    fn describe(&self) -> String {
        self.name.clone()
    }
}

/// Connects to a scanner's TCP address, again after every disconnect.
#[derive(Clone, Debug)]
pub struct TcpConnector {
    /// The scanner's address, e.g. 192.168.0.10:10940.
    pub addr: SocketAddr,
    /// Connect timeout.
    pub connect_timeout: Duration,
}

impl Connector for TcpConnector {
    fn open(&mut self, read_timeout: Duration) -> io::Result<Box<dyn Port>> {
        let stream = TcpStream::connect_timeout(&self.addr, self.connect_timeout)?;
        stream.set_nodelay(true)?;
        let mut p = TcpPort {
            stream,
            name: self.addr.to_string(),
        };
        p.set_read_timeout(read_timeout)?;
        Ok(Box::new(p))
    }
    fn present(&self) -> bool {
        true
    }
    fn describe(&self) -> String {
        self.addr.to_string()
    }
}
