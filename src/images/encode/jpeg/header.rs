//! The file's headers, and the tables the scan is coded with, both read
//! off one tiny encode by `jpeg-encoder`: its quality scaling, its
//! quantisation tables and its Huffman tables (the standard ones of
//! ITU-T T.81 Annex K) stay its own, and the scan written here cannot
//! disagree with the headers that describe it.

use super::ZIGZAG;

const MARKER: u8 = 0xFF;
const SOF0: u8 = 0xC0;
const DHT: u8 = 0xC4;
const DQT: u8 = 0xDB;
const SOS: u8 = 0xDA;

/// One quantisation table as the scan divides by it, in natural order:
/// `q = ((|v| + corr) * recip) >> 15`, with `v`'s sign, `jpeg-encoder`'s
/// rounding division by eight times the table's value (its DCT is scaled
/// by eight).
pub(super) struct Quant {
    pub recip: [i32; 64],
    pub corr: [i32; 64],
}

/// A Huffman table as the coder looks symbols up: the code and its length
/// in bits, zero for a symbol the table does not hold.
pub(super) struct Huff {
    pub code: [u16; 256],
    pub len: [u8; 256],
}

/// Tables by the number the headers give them: 0 for luma, 1 for chroma.
pub(super) struct Tables {
    pub quant: [Quant; 2],
    pub dc: [Huff; 2],
    pub ac: [Huff; 2],
}

/// Everything before the scan's first byte (SOI to the end of SOS) for a
/// `width` x `height` 4:4:4 image at `quality`, with a DRI segment when
/// `restart` (MCUs per restart interval) is given, and its tables.
pub(super) fn header(
    width: u16,
    height: u16,
    quality: u8,
    restart: Option<u16>,
) -> Result<(Vec<u8>, Tables), String> {
    let mut tiny = Vec::new();
    let mut e = jpeg_encoder::Encoder::new(&mut tiny, quality);
    e.set_sampling_factor(jpeg_encoder::SamplingFactor::F_1_1);
    if let Some(n) = restart {
        e.set_restart_interval(n);
    }
    e.encode(&[0; 8 * 8 * 3], 8, 8, jpeg_encoder::ColorType::Rgb)
        .map_err(|e| e.to_string())?;
    parse(tiny, width, height).ok_or_else(|| "the JPEG encoder wrote unexpected headers".into())
}

fn parse(mut bytes: Vec<u8>, width: u16, height: u16) -> Option<(Vec<u8>, Tables)> {
    let mut quant: [Option<Quant>; 2] = [None, None];
    let mut dc: [Option<Huff>; 2] = [None, None];
    let mut ac: [Option<Huff>; 2] = [None, None];
    let mut at = 2; // after SOI
    loop {
        let &[m, kind, hi, lo] = bytes.get(at..at + 4)? else {
            return None;
        };
        if m != MARKER {
            return None;
        }
        let len = usize::from(u16::from_be_bytes([hi, lo]));
        let body = bytes.get(at + 4..at + 2 + len)?;
        match kind {
            DQT => read_dqt(body, &mut quant)?,
            DHT => read_dht(body, &mut dc, &mut ac)?,
            SOF0 => {
                // precision (1), then height and width
                bytes
                    .get_mut(at + 5..at + 9)?
                    .copy_from_slice(&[height.to_be_bytes(), width.to_be_bytes()].concat());
            }
            SOS => {
                bytes.truncate(at + 2 + len);
                let [q0, q1] = quant;
                let [d0, d1] = dc;
                let [a0, a1] = ac;
                let tables = Tables {
                    quant: [q0?, q1?],
                    dc: [d0?, d1?],
                    ac: [a0?, a1?],
                };
                return Some((bytes, tables));
            }
            _ => {}
        }
        at += 2 + len;
    }
}

fn read_dqt(mut body: &[u8], quant: &mut [Option<Quant>; 2]) -> Option<()> {
    while let Some((&pq_tq, rest)) = body.split_first() {
        // 8-bit entries only: `jpeg-encoder` writes no others.
        if pq_tq >> 4 != 0 {
            return None;
        }
        let values = rest.get(..64)?;
        let mut q = Quant {
            recip: [0; 64],
            corr: [0; 64],
        };
        for (k, &v) in values.iter().enumerate() {
            let (recip, corr) = reciprocal(u32::from(v) * 8);
            let natural = usize::from(ZIGZAG[k]);
            q.recip[natural] = recip;
            q.corr[natural] = corr;
        }
        *quant.get_mut(usize::from(pq_tq & 15))? = Some(q);
        body = &rest[64..];
    }
    Some(())
}

/// `jpeg-encoder`'s reciprocal for a divisor (libjpeg-turbo's, without
/// its scale): division by `reciprocal`, rounding as `corr` makes it.
fn reciprocal(divisor: u32) -> (i32, i32) {
    const SHIFT: u32 = 15;
    if divisor <= 1 {
        return (1, 0);
    }
    let mut recip = (1 << SHIFT) / divisor;
    let fraction = (1 << SHIFT) % divisor;
    let mut corr = divisor / 2;
    if fraction != 0 {
        if fraction <= corr {
            corr += 1;
        } else {
            recip += 1;
        }
    }
    // Both under 2^16: the divisor is at most 255 * 8.
    (recip as i32, corr as i32)
}

fn read_dht(mut body: &[u8], dc: &mut [Option<Huff>; 2], ac: &mut [Option<Huff>; 2]) -> Option<()> {
    while let Some((&tc_th, rest)) = body.split_first() {
        let counts = rest.get(..16)?;
        let n: usize = counts.iter().map(|&c| usize::from(c)).sum();
        let values = rest.get(16..16 + n)?;
        let mut h = Huff {
            code: [0; 256],
            len: [0; 256],
        };
        // Canonical codes (T.81 Annex C): by length, each one more than
        // the last, doubled at every new length.
        let mut code = 0u32;
        let mut next = values.iter();
        for (bits, &count) in (1..=16u8).zip(counts) {
            for _ in 0..count {
                let &symbol = next.next()?;
                h.code[usize::from(symbol)] = u16::try_from(code).ok()?;
                h.len[usize::from(symbol)] = bits;
                code += 1;
            }
            code <<= 1;
        }
        let slot = match tc_th >> 4 {
            0 => dc.get_mut(usize::from(tc_th & 15))?,
            1 => ac.get_mut(usize::from(tc_th & 15))?,
            _ => return None,
        };
        *slot = Some(h);
        body = &rest[16 + n..];
    }
    Some(())
}
