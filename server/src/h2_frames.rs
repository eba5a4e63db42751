//! Which bytes of an HTTP/2 connection are progress: those of the frames that carry requests
//! and answers (HEADERS, CONTINUATION, DATA). PING, SETTINGS, WINDOW_UPDATE and the rest keep
//! a connection open without moving anything: counted as progress, a client sending a PING a
//! minute, or holding its streams' windows shut, held the connection and the answers buffered
//! on it for good.

const DATA: u8 = 0x0;
const HEADERS: u8 = 0x1;
const CONTINUATION: u8 = 0x9;

/// Frame types that are progress from the client: a request (its body, if any, is not read).
pub const FROM_CLIENT: &[u8] = &[HEADERS, CONTINUATION];
/// Frame types that are progress from the server: an answer.
pub const FROM_SERVER: &[u8] = &[HEADERS, CONTINUATION, DATA];

/// Follows the frames of one direction, given its bytes in order, however they are cut.
pub struct FrameScan {
    kinds: &'static [u8],
    head: [u8; 9],
    have: usize,
    /// Payload bytes of the current frame still to come.
    left: usize,
    /// Whether the current frame is one of `kinds`.
    moving: bool,
}

impl FrameScan {
    pub fn new(kinds: &'static [u8]) -> Self {
        FrameScan {
            kinds,
            head: [0; 9],
            have: 0,
            left: 0,
            moving: false,
        }
    }

    /// Takes the next bytes; whether any of them belong to a frame of `kinds`.
    pub fn feed(&mut self, mut bytes: &[u8]) -> bool {
        let mut moved = false;
        while !bytes.is_empty() {
            if self.left > 0 {
                let n = self.left.min(bytes.len());
                moved |= self.moving;
                self.left -= n;
                bytes = &bytes[n..];
                continue;
            }
            let n = (self.head.len() - self.have).min(bytes.len());
            self.head[self.have..self.have + n].copy_from_slice(&bytes[..n]);
            self.have += n;
            bytes = &bytes[n..];
            if self.have == self.head.len() {
                self.have = 0;
                let [a, b, c, kind, ..] = self.head;
                self.left = u32::from_be_bytes([0, a, b, c]) as usize;
                self.moving = self.kinds.contains(&kind);
                moved |= self.moving;
            }
        }
        moved
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(kind: u8, payload: &[u8]) -> Vec<u8> {
        let len = (payload.len() as u32).to_be_bytes();
        let mut f = vec![len[1], len[2], len[3], kind, 0, 0, 0, 0, 1];
        f.extend_from_slice(payload);
        f
    }

    #[test]
    fn only_requests_and_answers_are_progress_however_the_bytes_are_cut() {
        let ping = frame(0x6, &[7; 8]);
        let settings = frame(0x4, &[0, 4, 0, 0, 0, 0]);
        let data = frame(DATA, &[1; 300]);
        let stream: Vec<u8> = [ping.clone(), settings, data.clone(), ping.clone()].concat();
        let data_at = ping.len() + 15; // after the PING and the SETTINGS
        for cut in [1, 2, 5, 9, 17, 64, stream.len()] {
            let mut scan = FrameScan::new(FROM_SERVER);
            let mut moved_at = Vec::new();
            for (i, piece) in stream.chunks(cut).enumerate() {
                if scan.feed(piece) {
                    moved_at.push(i);
                }
            }
            // The pieces that hold a byte of the DATA frame from its header's last (where its
            // kind is known), and no others.
            let known = data_at + 8;
            let want: Vec<usize> = (0..stream.len().div_ceil(cut))
                .filter(|&i| i * cut < data_at + data.len() && (i + 1) * cut > known)
                .collect();
            assert_eq!(moved_at, want, "pieces of {cut} bytes");
        }
        // From the client, DATA is no progress (a GET has no body to read).
        assert!(!FrameScan::new(FROM_CLIENT).feed(&data));
        assert!(FrameScan::new(FROM_CLIENT).feed(&frame(HEADERS, &[0x82])));
    }
}
