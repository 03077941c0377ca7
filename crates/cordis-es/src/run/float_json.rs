//! f64 in JSON without loss, for checkpoints and reports: serde `with` modules.
//!
//! JSON has no infinities or NaN and serde_json rounds nothing only with `float_roundtrip`
//! (the workspace enables it): [`bits`] keeps vectors as IEEE bit patterns (checkpoints: a
//! resumed run must continue bit for bit), [`lossless`] keeps one number readable and writes
//! the non-finite ones as strings.

/// Exact f64 vectors in JSON (as IEEE bit patterns, so ±inf survive and nothing is rounded).
pub mod bits {
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    pub fn serialize<S: Serializer>(v: &[f64], s: S) -> Result<S::Ok, S::Error> {
        v.iter()
            .map(|x| x.to_bits())
            .collect::<Vec<u64>>()
            .serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<f64>, D::Error> {
        Ok(Vec::<u64>::deserialize(d)?
            .into_iter()
            .map(f64::from_bits)
            .collect())
    }
}

/// One f64 in JSON as a number when finite, else as the string `"inf"`, `"-inf"` or `"NaN"`
/// (JSON has no such numbers). Exact with serde_json's `float_roundtrip`.
pub mod lossless {
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
        if v.is_finite() {
            s.serialize_f64(*v)
        } else {
            s.serialize_str(&v.to_string())
        }
    }

    #[derive(Deserialize)]
    #[serde(untagged)]
    enum Repr {
        Num(f64),
        Text(String),
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
        match Repr::deserialize(d)? {
            Repr::Num(x) => Ok(x),
            Repr::Text(t) => t.parse().map_err(serde::de::Error::custom),
        }
    }

    /// One f64 written and read as above, for the containers below.
    #[derive(serde::Serialize, Deserialize)]
    struct Lossless(#[serde(with = "crate::run::float_json::lossless")] f64);

    /// Rows of f64, each as [`super::lossless`] writes one (a correlation matrix with rows
    /// not computed).
    pub mod matrix {
        use serde::ser::SerializeSeq;
        use serde::{Deserialize, Deserializer, Serializer};

        use super::Lossless;

        pub fn serialize<S: Serializer>(m: &[Vec<f64>], s: S) -> Result<S::Ok, S::Error> {
            let mut seq = s.serialize_seq(Some(m.len()))?;
            for row in m {
                let row: Vec<Lossless> = row.iter().map(|&x| Lossless(x)).collect();
                seq.serialize_element(&row)?;
            }
            seq.end()
        }

        pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<Vec<f64>>, D::Error> {
            let rows = Vec::<Vec<Lossless>>::deserialize(d)?;
            Ok(rows
                .into_iter()
                .map(|r| r.into_iter().map(|w| w.0).collect())
                .collect())
        }
    }

    /// A pair of f64 (an interval's ends) as a two-element array, each as
    /// [`super::lossless`] writes one.
    pub mod pair {
        use serde::{Deserialize, Deserializer, Serialize, Serializer};

        use super::Lossless;

        pub fn serialize<S: Serializer>(v: &(f64, f64), s: S) -> Result<S::Ok, S::Error> {
            (Lossless(v.0), Lossless(v.1)).serialize(s)
        }

        pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<(f64, f64), D::Error> {
            let (a, b) = <(Lossless, Lossless)>::deserialize(d)?;
            Ok((a.0, b.0))
        }
    }

    pub mod option {
        use serde::{Deserialize, Deserializer, Serializer};

        pub fn serialize<S: Serializer>(v: &Option<f64>, s: S) -> Result<S::Ok, S::Error> {
            match v {
                Some(x) => super::serialize(x, s),
                None => s.serialize_none(),
            }
        }

        pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<f64>, D::Error> {
            Ok(Option::<super::Lossless>::deserialize(d)?.map(|w| w.0))
        }
    }
}

#[cfg(test)]
mod tests {
    #[derive(Debug, PartialEq, serde::Serialize, serde::Deserialize)]
    struct Interval(#[serde(with = "super::lossless::pair")] (f64, f64));

    /// Guards the interval's JSON: an infinite end is the string `lossless` writes (serde
    /// wrote it `null`, which reads back as no number), finite ends stay numbers, and both
    /// read back bit for bit.
    #[test]
    fn a_pair_keeps_infinite_ends_as_strings_and_reads_back_exactly() {
        for (pair, text) in [
            ((0.0, f64::INFINITY), r#"[0.0,"inf"]"#),
            ((f64::NEG_INFINITY, 2.5), r#"["-inf",2.5]"#),
            ((0.1, 1e-300), "[0.1,1e-300]"),
        ] {
            let written = serde_json::to_string(&Interval(pair)).unwrap();
            assert_eq!(written, text);
            assert_eq!(
                serde_json::from_str::<Interval>(&written).unwrap(),
                Interval(pair)
            );
        }
        // Numbers written before the change (plain JSON numbers) still read.
        let old: Interval = serde_json::from_str("[1, 100]").unwrap();
        assert_eq!(old, Interval((1.0, 100.0)));
    }
}
