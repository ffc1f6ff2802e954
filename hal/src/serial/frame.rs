//! Framing: payload + CRC-16 (little endian), COBS-encoded, terminated by a 0x00 byte.
//! COBS makes 0x00 occur only as the delimiter, so a receiver resynchronises at the next
//! 0x00 after any corruption.

use crc::{CRC_16_IBM_3740, Crc};

/// CRC-16/IBM-3740 (also known as CRC-16/CCITT-FALSE): poly 0x1021, init 0xFFFF.
pub const CRC: Crc<u16> = Crc::<u16>::new(&CRC_16_IBM_3740);

/// Largest payload a frame carries: versions 1 to 3 stay within 64 bytes (a version 3 reply
/// for 6 axes and the spindle is 63), version 4 within 80 (its reply with 6 axes, the spindle
/// and homing is 71, its request with the safe output word 69).
pub const MAX_PAYLOAD: usize = 80;
/// Largest encoded frame: payload + CRC, COBS overhead, delimiter.
pub const MAX_FRAME: usize = cobs::max_encoding_length(MAX_PAYLOAD + 2) + 1;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameError {
    /// More bytes than any valid frame before a delimiter.
    TooLong,
    /// Not valid COBS.
    Encoding,
    /// Shorter than a CRC, or the CRC does not match.
    Crc,
}

/// Encodes `payload` (at most [`MAX_PAYLOAD`] bytes) into `out`; returns the frame length.
pub fn encode(payload: &[u8], out: &mut [u8; MAX_FRAME]) -> usize {
    let n = payload.len().min(MAX_PAYLOAD);
    let mut raw = [0u8; MAX_PAYLOAD + 2];
    raw[..n].copy_from_slice(&payload[..n]);
    raw[n..n + 2].copy_from_slice(&CRC.checksum(&payload[..n]).to_le_bytes());
    let len = cobs::encode(&raw[..n + 2], &mut out[..MAX_FRAME - 1]);
    out[len] = 0;
    len + 1
}

/// Collects bytes into frames. Fixed buffer, no allocation.
pub struct Decoder {
    buf: [u8; MAX_FRAME],
    len: usize,
    overflow: bool,
}

impl Default for Decoder {
    fn default() -> Self {
        Decoder {
            buf: [0; MAX_FRAME],
            len: 0,
            overflow: false,
        }
    }
}

impl Decoder {
    /// Forgets a partial frame (after the link was reopened).
    pub fn clear(&mut self) {
        self.len = 0;
        self.overflow = false;
    }

    /// Feeds received bytes; calls `on_frame` with each complete frame's payload (CRC checked
    /// and removed) or the reason it was rejected.
    pub fn feed(&mut self, bytes: &[u8], mut on_frame: impl FnMut(Result<&[u8], FrameError>)) {
        for &b in bytes {
            if b != 0 {
                if self.len < self.buf.len() {
                    self.buf[self.len] = b;
                    self.len += 1;
                } else {
                    self.overflow = true;
                }
                continue;
            }
            // Delimiter: decode what was collected. Empty frames (repeated 0x00) are idle fill.
            let len = std::mem::take(&mut self.len);
            if std::mem::take(&mut self.overflow) {
                on_frame(Err(FrameError::TooLong));
                continue;
            }
            if len == 0 {
                continue;
            }
            match cobs::decode_in_place(&mut self.buf[..len]) {
                Err(_) => on_frame(Err(FrameError::Encoding)),
                Ok(n) if n < 2 => on_frame(Err(FrameError::Crc)),
                Ok(n) => {
                    let (payload, crc) = self.buf[..n].split_at(n - 2);
                    if CRC.checksum(payload).to_le_bytes() == crc {
                        on_frame(Ok(payload));
                    } else {
                        on_frame(Err(FrameError::Crc));
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn decode_all(bytes: &[u8]) -> Vec<Result<Vec<u8>, FrameError>> {
        let mut d = Decoder::default();
        let mut out = Vec::new();
        // Byte by byte: frames may arrive split over many reads.
        for b in bytes {
            d.feed(std::slice::from_ref(b), |r| out.push(r.map(<[u8]>::to_vec)));
        }
        out
    }

    #[test]
    fn round_trip_with_zeros_and_split_reads() {
        let payload = [0x01, 0x00, 0x03, 0, 0, 0x10, 0x00, 0xFF];
        let mut f = [0u8; MAX_FRAME];
        let n = encode(&payload, &mut f);
        assert_eq!(f[n - 1], 0);
        assert!(
            !f[..n - 1].contains(&0),
            "COBS leaves only the delimiter zero"
        );
        let mut stream = vec![0, 0];
        stream.extend_from_slice(&f[..n]);
        stream.extend_from_slice(&f[..n]);
        assert_eq!(
            decode_all(&stream),
            vec![Ok(payload.to_vec()), Ok(payload.to_vec())]
        );
    }

    #[test]
    fn every_single_bit_flip_is_rejected() {
        let payload = [0x81, 7, 1, 0x37, 0x02, 1, 2, 3, 4, 0, 0];
        let mut f = [0u8; MAX_FRAME];
        let n = encode(&payload, &mut f);
        for byte in 0..n - 1 {
            for bit in 0..8 {
                let mut g = f;
                g[byte] ^= 1 << bit;
                let got = decode_all(&g[..n]);
                assert!(
                    got.iter()
                        .all(|r| r.as_ref().map_or(true, |p| p != &payload)),
                    "flip {byte}.{bit} accepted: {got:?}"
                );
                assert!(got.iter().all(Result::is_err), "flip {byte}.{bit}: {got:?}");
            }
        }
    }

    #[test]
    fn garbage_resynchronises() {
        let mut stream = vec![0x55; 300];
        stream.push(0);
        let mut f = [0u8; MAX_FRAME];
        let n = encode(&[1, 2, 3], &mut f);
        stream.extend_from_slice(&f[..n]);
        let got = decode_all(&stream);
        assert_eq!(got, vec![Err(FrameError::TooLong), Ok(vec![1, 2, 3])]);
    }
}
