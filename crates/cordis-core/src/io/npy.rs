//! NumPy `.npy` trajectories: float64 (or float32) arrays of shape `(T, N, 3)`.
//!
//! Hand-written rather than taken from `npyz`: we need one dtype and one rank, and we want
//! every malformed file to give a placed one-line error, with the shape checked against the
//! data length *before* anything is allocated (a crafted header must not ask for terabytes).
//! `npyz` handles every dtype through a Python-literal parser (`py_literal`, `num-bigint`),
//! reports `io::Error`s without places, and would still leave the rank/shape checks to us.
//!
//! Read: format versions 1.0, 2.0 and 3.0; dtype `<f8`/`>f8`, or `<f4`/`>f4` widened to f64;
//! C order, or Fortran order (transposed to C order on reading). Written: version 1.0, `<f8`, C order, header padded
//! so the data starts on a 64-byte boundary, as NumPy does.

use crate::error::{CordisError, Result};
use crate::{Observations, Trajectory};

const MAGIC: &[u8] = b"\x93NUMPY";

/// Parses `.npy` bytes; `name` is the place of header errors.
pub fn parse_npy(name: &str, bytes: &[u8]) -> Result<Trajectory> {
    let (t, n, values) = parse_values(name, bytes)?;
    Trajectory::from_flat(t, n, values).map_err(|e| placed(name, e))
}

/// Parses `.npy` bytes whose NaN values are missing observations (±inf is still refused).
pub fn parse_npy_observations(name: &str, bytes: &[u8]) -> Result<Observations> {
    let (t, n, values) = parse_values(name, bytes)?;
    Observations::from_flat(t, n, values).map_err(|e| placed(name, e))
}

fn placed(name: &str, e: CordisError) -> CordisError {
    match e {
        CordisError::Trajectory { place, message } => {
            CordisError::trajectory(format!("{name}: {place}"), message)
        }
        e => e,
    }
}

/// The header and the data bytes of `.npy` bytes (any dtype, any shape).
fn split_header<'a>(name: &str, bytes: &'a [u8]) -> Result<(Header, &'a [u8])> {
    let err = |m: String| CordisError::format(name, m);
    if bytes.len() < 10 || !bytes.starts_with(MAGIC) {
        return Err(err(
            "not a .npy file: it does not start with the magic `\\x93NUMPY`".into(),
        ));
    }
    let (major, minor) = (bytes[6], bytes[7]);
    let (header_len, start): (usize, usize) = match major {
        1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10),
        2 | 3 => {
            let Some(b) = bytes.get(8..12) else {
                return Err(err("file ends inside the header length".into()));
            };
            (u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize, 12)
        }
        _ => {
            return Err(err(format!(
                "format version {major}.{minor} is not supported (1.0, 2.0 or 3.0)"
            )))
        }
    };
    let Some(raw) = bytes.get(start..start.saturating_add(header_len)) else {
        return Err(err(format!(
            "file ends inside the header ({header_len} bytes announced)"
        )));
    };
    // Versions 1 and 2 declare the header Latin-1; version 3 UTF-8. Only ASCII matters here.
    let header: String = if major == 3 {
        std::str::from_utf8(raw)
            .map_err(|_| err("the header is not UTF-8".into()))?
            .to_owned()
    } else {
        raw.iter().map(|&b| b as char).collect()
    };
    let dict = parse_header(&header).map_err(|m| err(format!("header: {m}")))?;
    Ok((dict, &bytes[start + header_len..]))
}

/// The shape and the C-order values of `.npy` bytes: float64, or float32 widened (exactly)
/// to f64 — what a tracker or `np.float32` positions save, and what Python's `identify`
/// accepts as an array (the CLI refused the file).
fn parse_values(name: &str, bytes: &[u8]) -> Result<(usize, usize, Vec<f64>)> {
    let err = |m: String| CordisError::format(name, m);
    let (dict, data) = split_header(name, bytes)?;
    let (width, big_endian) = match dict.descr.as_str() {
        "<f8" => (8, false),
        ">f8" => (8, true),
        "<f4" => (4, false),
        ">f4" => (4, true),
        d => {
            return Err(err(format!(
                "dtype `{d}` is not read: expected float64 ('<f8', '>f8') or float32 ('<f4', \
                 '>f4')"
            )))
        }
    };
    let [t, n, three] = dict.shape[..] else {
        return Err(err(format!(
            "shape {:?} is not (frames, particles, 3)",
            dict.shape
        )));
    };
    if three != 3 {
        return Err(err(format!(
            "shape ({t}, {n}, {three}) is not (frames, particles, 3)"
        )));
    }
    if t == 0 || n == 0 {
        return Err(err(format!(
            "shape ({t}, {n}, 3) is empty: a trajectory needs at least one frame and one particle"
        )));
    }
    let count = t.checked_mul(n).and_then(|tn| tn.checked_mul(3));
    if count.and_then(|c| c.checked_mul(width)) != Some(data.len()) {
        return Err(err(format!(
            "shape ({t}, {n}, 3) needs {} bytes of float{} data, the file holds {}",
            count.map_or("more than 2^64".into(), |c| (c as u128 * width as u128)
                .to_string()),
            8 * width,
            data.len()
        )));
    }
    let values: Vec<f64> = data
        .chunks_exact(width)
        .map(|b| decode(b, Element::Float, big_endian))
        .collect();
    let values = match dict.fortran_order {
        true => fortran_to_c(&dict.shape, &values),
        false => values,
    };
    Ok((t, n, values))
}

/// An array of any rank read from `.npy` bytes, its values widened to f64 in C order.
#[derive(Clone, Debug, PartialEq)]
pub struct NpyArray {
    pub shape: Vec<usize>,
    pub values: Vec<f64>,
}

/// The element types [`parse_npy_array`] reads: floats, integers and booleans of any byte
/// order (a tracker saves float32 positions and boolean visibility).
#[derive(Clone, Copy)]
enum Element {
    Float,
    Signed,
    Unsigned,
    Bool,
}

/// Parses `.npy` bytes of any shape and of a numeric or boolean dtype (`f4`, `f8`, `i1`…`i8`,
/// `u1`…`u8`, `b1`, either byte order); the shape is checked against the data length before
/// anything is allocated. Used for tracker output (`tracks`, `visibility`).
pub fn parse_npy_array(name: &str, bytes: &[u8]) -> Result<NpyArray> {
    let err = |m: String| CordisError::format(name, m);
    let (dict, data) = split_header(name, bytes)?;
    let d = dict.descr.as_bytes();
    let (order, kind, size) = match d {
        [o @ (b'<' | b'>' | b'|' | b'='), k, s] => (*o, *k, *s),
        _ => return Err(err(format!("dtype `{}` is not a number type", dict.descr))),
    };
    let element = match (kind, size) {
        (b'f', b'4' | b'8') => Element::Float,
        (b'i', b'1' | b'2' | b'4' | b'8') => Element::Signed,
        (b'u', b'1' | b'2' | b'4' | b'8') => Element::Unsigned,
        (b'b', b'1') => Element::Bool,
        _ => {
            return Err(err(format!(
                "dtype `{}` is not read: expected a float (f4, f8), an integer or a boolean",
                dict.descr
            )))
        }
    };
    let width = (size - b'0') as usize;
    let big = order == b'>';
    let count = dict
        .shape
        .iter()
        .try_fold(1usize, |acc, &d| acc.checked_mul(d));
    if count.and_then(|c| c.checked_mul(width)) != Some(data.len()) {
        return Err(err(format!(
            "shape {:?} of `{}` needs {} bytes of data, the file holds {}",
            dict.shape,
            dict.descr,
            count.map_or("more than 2^64".into(), |c| (c as u128 * width as u128)
                .to_string()),
            data.len()
        )));
    }
    let values: Vec<f64> = data
        .chunks_exact(width)
        .map(|b| decode(b, element, big))
        .collect();
    let values = if dict.fortran_order && dict.shape.len() > 1 {
        fortran_to_c(&dict.shape, &values)
    } else {
        values
    };
    Ok(NpyArray {
        shape: dict.shape,
        values,
    })
}

/// One element of `width = b.len()` bytes as f64.
fn decode(b: &[u8], element: Element, big: bool) -> f64 {
    let mut raw = [0u8; 8];
    if big {
        raw[8 - b.len()..].copy_from_slice(b);
    } else {
        raw[..b.len()].copy_from_slice(b);
    }
    let bits = if big {
        u64::from_be_bytes(raw)
    } else {
        u64::from_le_bytes(raw)
    };
    let bits_len = 8 * b.len() as u32;
    match element {
        Element::Float if b.len() == 4 => f32::from_bits(bits as u32) as f64,
        Element::Float => f64::from_bits(bits),
        Element::Unsigned | Element::Bool => bits as f64,
        Element::Signed => {
            // Sign-extend the `bits_len`-bit value.
            let shift = 64 - bits_len;
            (((bits << shift) as i64) >> shift) as f64
        }
    }
}

/// C-order values of an array stored in Fortran order (first index fastest).
fn fortran_to_c(shape: &[usize], values: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; values.len()];
    let mut index = vec![0usize; shape.len()];
    for v in out.iter_mut() {
        // `index` runs in C order; its Fortran offset is sum index[k] * prod shape[..k].
        let (mut offset, mut stride) = (0, 1);
        for (k, &i) in index.iter().enumerate() {
            offset += i * stride;
            stride *= shape[k];
        }
        *v = values[offset];
        for k in (0..shape.len()).rev() {
            index[k] += 1;
            if index[k] < shape[k] {
                break;
            }
            index[k] = 0;
        }
    }
    out
}

/// `.npy` bytes (version 1.0, `<f8`, C order) of a trajectory.
pub fn write_npy(traj: &Trajectory) -> Vec<u8> {
    write_npy_values(traj.frames(), traj.particles(), traj.as_flat())
}

/// `.npy` bytes of `(frames, particles, 3)` row-major values (NaN kept: missing observations).
pub fn write_npy_values(frames: usize, particles: usize, values: &[f64]) -> Vec<u8> {
    let mut header = format!(
        "{{'descr': '<f8', 'fortran_order': False, 'shape': ({frames}, {particles}, 3), }}"
    );
    // Magic (6) + version (2) + length (2) + header + '\n' is a multiple of 64.
    let pad = (64 - (10 + header.len() + 1) % 64) % 64;
    header.extend(std::iter::repeat_n(' ', pad));
    header.push('\n');
    let mut out = Vec::with_capacity(10 + header.len() + values.len() * 8);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&[1, 0]);
    // A 3-D shape's header is far below 65535 bytes.
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    for v in values {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}

#[derive(Debug)]
struct Header {
    descr: String,
    fortran_order: bool,
    shape: Vec<usize>,
}

/// Parses the header's Python dict literal: `{'descr': '<f8', 'fortran_order': False,
/// 'shape': (2, 3, 3), }`. Only the three keys NumPy writes are allowed.
fn parse_header(text: &str) -> std::result::Result<Header, String> {
    let mut p = Lexer {
        s: text.trim_end_matches(['\n', ' ', '\0']).as_bytes(),
        i: 0,
    };
    p.expect(b'{')?;
    let (mut descr, mut fortran, mut shape) = (None, None, None);
    loop {
        if p.eat(b'}') {
            break;
        }
        let key = p.string()?;
        p.expect(b':')?;
        match key.as_str() {
            "descr" if descr.is_none() => descr = Some(p.string()?),
            "fortran_order" if fortran.is_none() => fortran = Some(p.boolean()?),
            "shape" if shape.is_none() => shape = Some(p.tuple()?),
            "descr" | "fortran_order" | "shape" => return Err(format!("key '{key}' is repeated")),
            _ => return Err(format!("unexpected key '{key}'")),
        }
        if !p.eat(b',') {
            p.expect(b'}')?;
            break;
        }
    }
    p.skip_ws();
    if p.i != p.s.len() {
        return Err("text after the closing `}`".into());
    }
    Ok(Header {
        descr: descr.ok_or("no 'descr' key")?,
        fortran_order: fortran.ok_or("no 'fortran_order' key")?,
        shape: shape.ok_or("no 'shape' key")?,
    })
}

struct Lexer<'a> {
    s: &'a [u8],
    i: usize,
}

impl Lexer<'_> {
    fn skip_ws(&mut self) {
        while self.s.get(self.i).is_some_and(|c| c.is_ascii_whitespace()) {
            self.i += 1;
        }
    }

    fn eat(&mut self, c: u8) -> bool {
        self.skip_ws();
        if self.s.get(self.i) == Some(&c) {
            self.i += 1;
            true
        } else {
            false
        }
    }

    fn expect(&mut self, c: u8) -> std::result::Result<(), String> {
        if self.eat(c) {
            Ok(())
        } else {
            Err(format!("expected `{}` at byte {}", c as char, self.i))
        }
    }

    fn string(&mut self) -> std::result::Result<String, String> {
        self.skip_ws();
        let quote = match self.s.get(self.i) {
            Some(&q @ (b'\'' | b'"')) => q,
            _ => return Err(format!("expected a quoted string at byte {}", self.i)),
        };
        let start = self.i + 1;
        let len = self.s[start..]
            .iter()
            .position(|&c| c == quote)
            .ok_or("unterminated string")?;
        self.i = start + len + 1;
        Ok(String::from_utf8_lossy(&self.s[start..start + len]).into_owned())
    }

    fn boolean(&mut self) -> std::result::Result<bool, String> {
        self.skip_ws();
        for (word, v) in [("True", true), ("False", false)] {
            if self.s[self.i..].starts_with(word.as_bytes()) {
                self.i += word.len();
                return Ok(v);
            }
        }
        Err(format!("expected True or False at byte {}", self.i))
    }

    fn tuple(&mut self) -> std::result::Result<Vec<usize>, String> {
        self.expect(b'(')?;
        let mut dims = Vec::new();
        loop {
            if self.eat(b')') {
                return Ok(dims);
            }
            self.skip_ws();
            let start = self.i;
            while self.s.get(self.i).is_some_and(u8::is_ascii_digit) {
                self.i += 1;
            }
            let digits = std::str::from_utf8(&self.s[start..self.i]).unwrap_or("");
            // Python 2 wrote long integers as `3L`.
            if self.s.get(self.i) == Some(&b'L') {
                self.i += 1;
            }
            dims.push(
                digits
                    .parse::<usize>()
                    .map_err(|_| format!("expected a dimension at byte {start}"))?,
            );
            if !self.eat(b',') {
                self.expect(b')')?;
                return Ok(dims);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn npy_bytes(descr: &str, fortran: bool, shape: &str, data: &[u8]) -> Vec<u8> {
        let fo = if fortran { "True" } else { "False" };
        let header = format!("{{'descr': '{descr}', 'fortran_order': {fo}, 'shape': {shape}, }}\n");
        let mut out = MAGIC.to_vec();
        out.extend_from_slice(&[1, 0]);
        out.extend_from_slice(&(header.len() as u16).to_le_bytes());
        out.extend_from_slice(header.as_bytes());
        out.extend_from_slice(data);
        out
    }

    #[test]
    fn arrays_of_any_rank_and_number_type_widen_to_f64() {
        let f4: Vec<u8> = [1.5f32, -2.0, 3.25, 0.0, 5.0, 6.0]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let a = parse_npy_array("t.npy", &npy_bytes("<f4", false, "(2, 3)", &f4)).unwrap();
        assert_eq!(a.shape, [2, 3]);
        assert_eq!(a.values, [1.5, -2.0, 3.25, 0.0, 5.0, 6.0]);
        // Fortran order: the same bytes are the transpose.
        let a = parse_npy_array("t.npy", &npy_bytes("<f4", true, "(3, 2)", &f4)).unwrap();
        assert_eq!(a.values, [1.5, 0.0, -2.0, 5.0, 3.25, 6.0]);
        let b = parse_npy_array("v.npy", &npy_bytes("|b1", false, "(3,)", &[1, 0, 1])).unwrap();
        assert_eq!(b.values, [1.0, 0.0, 1.0]);
        let i: Vec<u8> = [-3i16, 7].iter().flat_map(|v| v.to_be_bytes()).collect();
        let a = parse_npy_array("i.npy", &npy_bytes(">i2", false, "(2,)", &i)).unwrap();
        assert_eq!(a.values, [-3.0, 7.0]);
        let e = parse_npy_array("t.npy", &npy_bytes("<f4", false, "(2, 4)", &f4))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("t.npy: shape [2, 4] of `<f4` needs 32 bytes"),
            "{e}"
        );
        let e = parse_npy_array("t.npy", &npy_bytes("<U3", false, "(2,)", &f4))
            .unwrap_err()
            .to_string();
        assert!(e.contains("dtype `<U3` is not read"), "{e}");
    }

    #[test]
    fn a_float32_trajectory_is_read_widened_like_pythons() {
        // The CLI refused a float32 `.npy` that `cordis.identify` took as an array.
        let v = [0.1f32, -2.0, 3.25, f32::NAN, 5.0, 6.0];
        let le: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
        let be: Vec<u8> = v.iter().flat_map(|x| x.to_be_bytes()).collect();
        let widened: Vec<f64> = v.iter().map(|&x| x as f64).collect();
        for (descr, data) in [("<f4", &le), (">f4", &be)] {
            let o = parse_npy_observations("t.npy", &npy_bytes(descr, false, "(1, 2, 3)", data))
                .unwrap();
            let got = o.as_flat();
            assert_eq!(got[..3], widened[..3], "{descr}");
            assert!(got[3].is_nan() && got[4..] == widened[4..], "{descr}");
        }
        // Fortran order: (f, i, k) at f + T (i + N k).
        let f: Vec<u8> = [1.0f32, 2.0, 3.0, 4.0, 5.0, 6.0]
            .iter()
            .flat_map(|x| x.to_le_bytes())
            .collect();
        let t = parse_npy("t.npy", &npy_bytes("<f4", true, "(2, 1, 3)", &f)).unwrap();
        assert_eq!(t.as_flat(), [1.0, 3.0, 5.0, 2.0, 4.0, 6.0]);
        let e = parse_npy("t.npy", &npy_bytes("<f4", false, "(1, 2, 3)", &le[..20]))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("shape (1, 2, 3) needs 24 bytes of float32 data, the file holds 20"),
            "{e}"
        );
        let e = parse_npy("t.npy", &npy_bytes("<f2", false, "(1, 1, 3)", &[0; 6]))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("dtype `<f2` is not read: expected float64 ('<f8', '>f8') or float32"),
            "{e}"
        );
    }

    #[test]
    fn header_is_padded_to_64_bytes() {
        let t = Trajectory::zeros(2, 5);
        let b = write_npy(&t);
        let hl = u16::from_le_bytes([b[8], b[9]]) as usize;
        assert_eq!((10 + hl) % 64, 0);
        assert_eq!(b[10 + hl - 1], b'\n');
        assert_eq!(b.len(), 10 + hl + 2 * 5 * 3 * 8);
    }

    #[test]
    fn header_literal_variants() {
        let h =
            parse_header("{\"shape\": (4L, 2L, 3L), 'fortran_order':True,'descr':'>f8'}").unwrap();
        assert_eq!(h.shape, [4, 2, 3]);
        assert!(h.fortran_order);
        assert_eq!(h.descr, ">f8");
        assert!(parse_header("{'descr': '<f8', 'fortran_order': False}").is_err());
        assert!(parse_header("{'descr': '<f8', 'descr': '<f8'}").is_err());
    }
}
