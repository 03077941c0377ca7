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
