//! A fixed-capacity outgoing byte queue: the core appends whole packets, the shell sends from
//! the front and says how much went out.

use heapless::Vec;

/// Outgoing bytes of one link.
#[derive(Debug, Clone, Default)]
pub struct TxBuf<const N: usize> {
    bytes: Vec<u8, N>,
}

impl<const N: usize> TxBuf<N> {
    /// An empty queue.
    pub const fn new() -> Self {
        Self { bytes: Vec::new() }
    }

    /// Append a whole packet; false (and nothing appended) when it does not fit.
    pub fn push(&mut self, packet: &[u8]) -> bool {
        self.bytes.extend_from_slice(packet).is_ok()
    }

    /// Bytes waiting to be sent.
    pub fn pending(&self) -> &[u8] {
        &self.bytes
    }

    /// The first `n` pending bytes were sent.
    pub fn consume(&mut self, n: usize) {
        let n = n.min(self.bytes.len());
        self.bytes.copy_within(n.., 0);
        self.bytes.truncate(self.bytes.len().saturating_sub(n));
    }
}
