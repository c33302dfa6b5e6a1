//! Token helpers shared by the emitters: the scalar type, literals that round-trip
//! exactly, unsuffixed integers, the runtime path, and joining fragments.
//!
//! Every emitter builds `proc_macro2` token trees with `quote!`; this module is the
//! one place that decides how a number is spelled in the generated source. Integers
//! are unsuffixed (`5`, as array lengths and indices are written by hand); floats are
//! suffixed literals in Rust's shortest round-trip form, so parsing the generated
//! source gives back exactly the value the generator computed.

use std::str::FromStr;

use proc_macro2::{Delimiter, Group, Ident, Literal, Span, TokenStream, TokenTree};
use quote::{ToTokens, format_ident, quote};

use super::Precision;

/// The runtime's private helper module, as written into generated code
/// (`::graphspn_runtime::__private`); append `::item`.
pub fn rt() -> TokenStream {
    quote!(::graphspn_runtime::__private)
}

/// An unsuffixed integer literal (`5`, not `5usize`).
pub fn int(n: usize) -> Literal {
    Literal::usize_unsuffixed(n)
}

/// An unsuffixed hexadecimal integer literal (`0x1f`), as decomposition bit sets are
/// written.
pub fn hex(n: u64) -> Literal {
    // The spelling of a number, not Rust source: a hexadecimal numeral always lexes
    // as one literal; should it not, the decimal literal has the same value.
    // lint: spelling of one numeric literal
    let text = format!("{n:#x}");
    Literal::from_str(&text).unwrap_or_else(|_| Literal::u64_unsuffixed(n))
}

/// Scalar type and float literals of one precision.
pub struct Lit {
    /// `f32` or `f64`.
    pub t: &'static str,
    /// The scalar type as an identifier.
    ty: Ident,
    precision: Precision,
}

impl Lit {
    /// The literal printer for `precision`.
    pub fn new(precision: Precision) -> Self {
        let t = match precision {
            Precision::F32 => "f32",
            Precision::F64 => "f64",
        };
        Lit {
            t,
            ty: Ident::new(t, Span::call_site()),
            precision,
        }
    }

    /// The precision this printer was made for.
    pub fn precision(&self) -> Precision {
        self.precision
    }

    /// A runtime helper with the scalar type's suffix: `helper("sum")` is
    /// `::graphspn_runtime::__private::sum_f32`.
    pub fn helper(&self, name: &str) -> TokenStream {
        let rt = rt();
        let f = format_ident!("{}_{}", name, self.t);
        quote!(#rt::#f)
    }

    /// The scalar type (`f32` or `f64`).
    pub fn ty(&self) -> &Ident {
        &self.ty
    }

    /// Whether the scalar type is `f32`.
    pub fn is_f32(&self) -> bool {
        self.t == "f32"
    }

    /// A literal for `v` rounded to the scalar type: Rust's shortest round-trip form
    /// with a type suffix (`0.25f32`, `1e-5f32`), so parsing it gives back exactly the
    /// same value; negative values are a `-` token before the literal, as the lexer
    /// reads them. Infinities become `f32::INFINITY` / `f32::NEG_INFINITY` (and NaN
    /// `f32::NAN`, which validated inputs never produce).
    pub fn num(&self, v: f64) -> TokenStream {
        let ty = &self.ty;
        let f32 = self.is_f32();
        let x = if f32 { f64::from(v as f32) } else { v };
        if x.is_nan() {
            return quote!(#ty::NAN);
        }
        if x.is_infinite() {
            return if x > 0.0 {
                quote!(#ty::INFINITY)
            } else {
                quote!(#ty::NEG_INFINITY)
            };
        }
        // The shortest round-trip digits of the value in its own type.
        let (abs32, abs64) = ((v as f32).abs(), v.abs());
        let abs: &dyn std::fmt::Debug = if f32 { &abs32 } else { &abs64 };
        // lint: spelling of one numeric literal
        let text = format!("{abs:?}{}", self.t);
        let lit = Literal::from_str(&text).unwrap_or_else(|_| {
            if f32 {
                Literal::f32_suffixed(abs32)
            } else {
                Literal::f64_suffixed(abs64)
            }
        });
        if x.is_sign_negative() {
            quote!(- #lit)
        } else {
            lit.into_token_stream()
        }
    }
}

/// A token fragment that can be moved into a stream. Owned streams are moved tree by
/// tree (going through `ToTokens` would clone them, and extending with a shared
/// stream copies it: the tables of a 10,000-place map are hundreds of thousands of
/// such fragments).
pub trait Fragment {
    /// Appends the fragment's tokens to `out`.
    fn push_to(self, out: &mut TokenStream);
}

impl Fragment for TokenStream {
    fn push_to(self, out: &mut TokenStream) {
        out.extend(self);
    }
}

impl Fragment for Literal {
    fn push_to(self, out: &mut TokenStream) {
        out.extend(std::iter::once(TokenTree::Literal(self)));
    }
}

impl Fragment for Ident {
    fn push_to(self, out: &mut TokenStream) {
        out.extend(std::iter::once(TokenTree::Ident(self)));
    }
}

/// `items` separated by `sep` (e.g. `a * b * c` with `quote!(*)`).
pub fn join<I>(items: I, sep: &TokenStream) -> TokenStream
where
    I: IntoIterator,
    I::Item: Fragment,
{
    let sep: Vec<TokenTree> = sep.clone().into_iter().collect();
    let mut out = TokenStream::new();
    for (i, item) in items.into_iter().enumerate() {
        if i > 0 {
            out.extend(sep.iter().cloned());
        }
        item.push_to(&mut out);
    }
    out
}

/// `[a, b, c]`: an array expression of `items`.
pub fn array<I>(items: I) -> TokenStream
where
    I: IntoIterator,
    I::Item: Fragment,
{
    let inner = join(items, &quote!(,));
    TokenTree::Group(Group::new(Delimiter::Bracket, inner)).into()
}

/// Integer literals `items` as an array expression `[1, 2, 3]`.
pub fn int_array<I: IntoIterator<Item = usize>>(items: I) -> TokenStream {
    array(items.into_iter().map(int))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Infinities keep their sign (`ln` of a zero weight is `-∞`); finite values keep
    /// their digits, negative ones as a `-` token.
    #[test]
    fn literals_keep_signs_and_infinities() {
        let cases = [
            (
                Precision::F32,
                ["f32::INFINITY", "f32::NEG_INFINITY", "0.25f32", "-0.25f32"],
            ),
            (
                Precision::F64,
                ["f64::INFINITY", "f64::NEG_INFINITY", "0.25f64", "-0.25f64"],
            ),
        ];
        for (precision, expected) in cases {
            let l = Lit::new(precision);
            let values = [f64::INFINITY, f64::NEG_INFINITY, 0.25, -0.25];
            for (v, want) in values.into_iter().zip(expected) {
                assert_eq!(l.num(v).to_string().replace(' ', ""), want);
            }
        }
    }
}
