//! Small text-emission helpers: scalar literals that round-trip exactly.

use super::Precision;

/// Path of the runtime's private helper module, as written into generated code.
pub const P: &str = "::graphspn_runtime::__private::";

/// Scalar type name and literal printing for one precision.
pub struct Lit {
    /// `f32` or `f64`.
    pub t: &'static str,
}

impl Lit {
    /// The literal printer for `precision`.
    pub fn new(precision: Precision) -> Self {
        Lit {
            t: match precision {
                Precision::F32 => "f32",
                Precision::F64 => "f64",
            },
        }
    }

    /// A literal for `v` rounded to the scalar type: Rust's shortest round-trip
    /// `{:?}` form plus a type suffix, so parsing it gives back exactly the same
    /// value. Infinities become `f32::INFINITY` / `f32::NEG_INFINITY`.
    pub fn num(&self, v: f64) -> String {
        if self.t == "f32" {
            let x = v as f32;
            if x.is_infinite() {
                return if x > 0.0 {
                    "f32::INFINITY".into()
                } else {
                    "f32::NEG_INFINITY".into()
                };
            }
            format!("{x:?}f32")
        } else {
            if v.is_infinite() {
                return if v > 0.0 {
                    "f64::INFINITY".into()
                } else {
                    "f64::NEG_INFINITY".into()
                };
            }
            format!("{v:?}f64")
        }
    }
}
