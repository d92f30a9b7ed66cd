//! Forward-mode dual numbers and small generic vector maths.
//!
//! The contact-problem constraints are written once over a [`Scalar`] and evaluated either in
//! `f64` (values only) or in [`Dual<N>`] (values and exact first derivatives with respect to
//! `N` seeded inputs), which gives the analytic Jacobians CSVTO needs without hand-deriving
//! second derivatives of the kinematics and the signed distances.

// Index loops over small fixed-size arrays mirror the maths (rows, joints, faces).
#![allow(clippy::needless_range_loop)]

use std::ops::{Add, Div, Mul, Neg, Sub};

/// The number type the constraint code is generic over.
pub trait Scalar:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + Add<f64, Output = Self>
    + Sub<f64, Output = Self>
    + Mul<f64, Output = Self>
    + Div<f64, Output = Self>
    + std::fmt::Debug
{
    /// A constant.
    fn cst(v: f64) -> Self;
    /// The value part.
    fn val(self) -> f64;
    /// Sine.
    fn sin(self) -> Self;
    /// Cosine.
    fn cos(self) -> Self;
    /// Square root.
    fn sqrt(self) -> Self;
    /// Absolute value (derivative `sign(x)`).
    fn abs(self) -> Self {
        if self.val() < 0.0 { -self } else { self }
    }
}

impl Scalar for f64 {
    fn cst(v: f64) -> Self {
        v
    }
    fn val(self) -> f64 {
        self
    }
    fn sin(self) -> Self {
        f64::sin(self)
    }
    fn cos(self) -> Self {
        f64::cos(self)
    }
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }
}

/// A dual number: a value and its gradient with respect to `N` inputs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Dual<const N: usize> {
    /// Value.
    pub v: f64,
    /// Partial derivatives.
    pub d: [f64; N],
}

impl<const N: usize> Dual<N> {
    /// The `i`-th input variable with value `v`.
    pub fn var(v: f64, i: usize) -> Self {
        let mut d = [0.0; N];
        d[i] = 1.0;
        Self { v, d }
    }

    /// Apply a scalar function with value `f` and derivative `df` at `self.v`.
    #[inline]
    fn chain(self, f: f64, df: f64) -> Self {
        let mut d = self.d;
        for x in d.iter_mut() {
            *x *= df;
        }
        Self { v: f, d }
    }
}

impl<const N: usize> Add for Dual<N> {
    type Output = Self;
    #[inline]
    fn add(self, o: Self) -> Self {
        let mut d = self.d;
        for (a, b) in d.iter_mut().zip(o.d.iter()) {
            *a += b;
        }
        Self { v: self.v + o.v, d }
    }
}
impl<const N: usize> Sub for Dual<N> {
    type Output = Self;
    #[inline]
    fn sub(self, o: Self) -> Self {
        let mut d = self.d;
        for (a, b) in d.iter_mut().zip(o.d.iter()) {
            *a -= b;
        }
        Self { v: self.v - o.v, d }
    }
}
impl<const N: usize> Mul for Dual<N> {
    type Output = Self;
    #[inline]
    fn mul(self, o: Self) -> Self {
        let mut d = [0.0; N];
        for i in 0..N {
            d[i] = self.d[i] * o.v + o.d[i] * self.v;
        }
        Self { v: self.v * o.v, d }
    }
}
impl<const N: usize> Div for Dual<N> {
    type Output = Self;
    #[inline]
    fn div(self, o: Self) -> Self {
        let inv = 1.0 / o.v;
        let v = self.v * inv;
        let mut d = [0.0; N];
        for i in 0..N {
            d[i] = (self.d[i] - v * o.d[i]) * inv;
        }
        Self { v, d }
    }
}
impl<const N: usize> Neg for Dual<N> {
    type Output = Self;
    #[inline]
    fn neg(self) -> Self {
        self.chain(-self.v, -1.0)
    }
}
impl<const N: usize> Add<f64> for Dual<N> {
    type Output = Self;
    #[inline]
    fn add(self, o: f64) -> Self {
        Self {
            v: self.v + o,
            d: self.d,
        }
    }
}
impl<const N: usize> Sub<f64> for Dual<N> {
    type Output = Self;
    #[inline]
    fn sub(self, o: f64) -> Self {
        Self {
            v: self.v - o,
            d: self.d,
        }
    }
}
impl<const N: usize> Mul<f64> for Dual<N> {
    type Output = Self;
    #[inline]
    fn mul(self, o: f64) -> Self {
        self.chain(self.v * o, o)
    }
}
impl<const N: usize> Div<f64> for Dual<N> {
    type Output = Self;
    #[inline]
    fn div(self, o: f64) -> Self {
        self.chain(self.v / o, 1.0 / o)
    }
}

impl<const N: usize> Scalar for Dual<N> {
    fn cst(v: f64) -> Self {
        Self { v, d: [0.0; N] }
    }
    fn val(self) -> f64 {
        self.v
    }
    fn sin(self) -> Self {
        self.chain(self.v.sin(), self.v.cos())
    }
    fn cos(self) -> Self {
        self.chain(self.v.cos(), -self.v.sin())
    }
    fn sqrt(self) -> Self {
        let s = self.v.sqrt();
        self.chain(s, if s > 0.0 { 0.5 / s } else { 0.0 })
    }
}

/// A 3-vector over a [`Scalar`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct V3<S>(pub [S; 3]);

impl<S: Scalar> V3<S> {
    /// From constants.
    pub fn cst(v: [f64; 3]) -> Self {
        V3(v.map(S::cst))
    }
    /// The zero vector.
    pub fn zero() -> Self {
        Self::cst([0.0; 3])
    }
    /// Components `(x, y, z)`.
    pub fn x(&self) -> S {
        self.0[0]
    }
    /// `y`.
    pub fn y(&self) -> S {
        self.0[1]
    }
    /// `z`.
    pub fn z(&self) -> S {
        self.0[2]
    }
    /// `self + o`.
    pub fn add(&self, o: &Self) -> Self {
        V3([self.0[0] + o.0[0], self.0[1] + o.0[1], self.0[2] + o.0[2]])
    }
    /// `self − o`.
    pub fn sub(&self, o: &Self) -> Self {
        V3([self.0[0] - o.0[0], self.0[1] - o.0[1], self.0[2] - o.0[2]])
    }
    /// `s·self`.
    pub fn scale(&self, s: S) -> Self {
        V3([self.0[0] * s, self.0[1] * s, self.0[2] * s])
    }
    /// `s·self` for a constant `s`.
    pub fn scalef(&self, s: f64) -> Self {
        V3([self.0[0] * s, self.0[1] * s, self.0[2] * s])
    }
    /// Dot product.
    pub fn dot(&self, o: &Self) -> S {
        self.0[0] * o.0[0] + self.0[1] * o.0[1] + self.0[2] * o.0[2]
    }
    /// Dot product with a constant vector.
    pub fn dotf(&self, o: &[f64; 3]) -> S {
        self.0[0] * o[0] + self.0[1] * o[1] + self.0[2] * o[2]
    }
    /// Cross product.
    pub fn cross(&self, o: &Self) -> Self {
        let (a, b) = (&self.0, &o.0);
        V3([
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ])
    }
    /// Euclidean norm.
    pub fn norm(&self) -> S {
        self.dot(self).sqrt()
    }
    /// Values only.
    pub fn val(&self) -> [f64; 3] {
        self.0.map(|s| s.val())
    }
}

/// A 3×3 matrix over a [`Scalar`], row-major.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct M3<S>(pub [[S; 3]; 3]);

impl<S: Scalar> M3<S> {
    /// From constants.
    pub fn cst(m: [[f64; 3]; 3]) -> Self {
        M3(m.map(|r| r.map(S::cst)))
    }
    /// `self · v`.
    pub fn mul_v(&self, v: &V3<S>) -> V3<S> {
        V3(std::array::from_fn(|i| {
            self.0[i][0] * v.0[0] + self.0[i][1] * v.0[1] + self.0[i][2] * v.0[2]
        }))
    }
    /// `selfᵀ · v`.
    pub fn tmul_v(&self, v: &V3<S>) -> V3<S> {
        V3(std::array::from_fn(|i| {
            self.0[0][i] * v.0[0] + self.0[1][i] * v.0[1] + self.0[2][i] * v.0[2]
        }))
    }
    /// `self · o`.
    pub fn mul(&self, o: &Self) -> Self {
        M3(std::array::from_fn(|i| {
            std::array::from_fn(|j| {
                self.0[i][0] * o.0[0][j] + self.0[i][1] * o.0[1][j] + self.0[i][2] * o.0[2][j]
            })
        }))
    }
    /// `self · c` for a constant matrix `c`.
    pub fn mul_f(&self, c: &[[f64; 3]; 3]) -> Self {
        M3(std::array::from_fn(|i| {
            std::array::from_fn(|j| {
                self.0[i][0] * c[0][j] + self.0[i][1] * c[1][j] + self.0[i][2] * c[2][j]
            })
        }))
    }
    /// `self · selfᵀ`-style product `self · oᵀ`.
    pub fn mul_t(&self, o: &Self) -> Self {
        M3(std::array::from_fn(|i| {
            std::array::from_fn(|j| {
                self.0[i][0] * o.0[j][0] + self.0[i][1] * o.0[j][1] + self.0[i][2] * o.0[j][2]
            })
        }))
    }
    /// Rotation about the x axis.
    pub fn rot_x(a: S) -> Self {
        let (c, s, o, l) = (a.cos(), a.sin(), S::cst(0.0), S::cst(1.0));
        M3([[l, o, o], [o, c, -s], [o, s, c]])
    }
    /// Rotation about the y axis.
    pub fn rot_y(a: S) -> Self {
        let (c, s, o, l) = (a.cos(), a.sin(), S::cst(0.0), S::cst(1.0));
        M3([[c, o, s], [o, l, o], [-s, o, c]])
    }
    /// Rotation about the z axis.
    pub fn rot_z(a: S) -> Self {
        let (c, s, o, l) = (a.cos(), a.sin(), S::cst(0.0), S::cst(1.0));
        M3([[c, -s, o], [s, c, o], [o, o, l]])
    }
    /// Rotation by angle `a` about the constant unit axis `k` (Rodrigues).
    pub fn rot_axis(k: &[f64; 3], a: S) -> Self {
        let (c, s) = (a.cos(), a.sin());
        let t = S::cst(1.0) - c;
        let [x, y, z] = *k;
        M3([
            [c + t * (x * x), t * (x * y) - s * z, t * (x * z) + s * y],
            [t * (x * y) + s * z, c + t * (y * y), t * (y * z) - s * x],
            [t * (x * z) - s * y, t * (y * z) + s * x, c + t * (z * z)],
        ])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dual_derivatives_match_calculus() {
        let x = Dual::<2>::var(0.7, 0);
        let y = Dual::<2>::var(-1.3, 1);
        let f = (x * y).sin() + (x * x + y * y).sqrt() / y - x * 2.0;
        let (xv, yv) = (0.7f64, -1.3f64);
        let r = (xv * xv + yv * yv).sqrt();
        let dfdx = (xv * yv).cos() * yv + xv / r / yv - 2.0;
        let dfdy = (xv * yv).cos() * xv + (yv / r * yv - r) / (yv * yv);
        assert!((f.d[0] - dfdx).abs() < 1e-12);
        assert!((f.d[1] - dfdy).abs() < 1e-12);
    }

    #[test]
    fn rodrigues_matches_axis_rotations() {
        let a = 0.4f64;
        let r = M3::<f64>::rot_axis(&[0.0, 1.0, 0.0], a);
        let ry = M3::<f64>::rot_y(a);
        for i in 0..3 {
            for j in 0..3 {
                assert!((r.0[i][j] - ry.0[i][j]).abs() < 1e-15);
            }
        }
    }
}
