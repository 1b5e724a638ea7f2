//! A conforming-device emulator: device floats whose every operation returns a result that
//! the WGSL and Vulkan specifications allow, chosen adversarially from a seeded stream, so
//! that code proven for "any conforming device" can be tested without one.
//!
//! What the specifications promise (Vulkan, "Precision and Operation of SPIR-V
//! Instructions"; WGSL, "Floating Point Accuracy"), and what [`Emu32`] and [`Emu64`] do:
//!
//! - `+ - *` are correctly rounded, in a rounding mode the specifications leave open (to
//!   nearest or toward zero): the emulator returns either neighbour of the exact result (at
//!   most 1 ulp off; the exact result itself where it is representable). A multiply-add may
//!   also be fused into one rounding: an addition or subtraction whose second operand is
//!   the result of the operation just before it, a multiplication, takes the exact product
//!   half the time.
//! - Subnormal operands and results may be flushed to zero (sign kept): the emulator flips
//!   a coin for each, results of division and the built-in functions included, and so do
//!   the operands of a comparison (`<`, `==`: a subnormal may compare as zero).
//! - `x / y`: within 2.5 ulp for |y| in [2^-126, 2^126], anything outside that range.
//! - f32 `exp`: 3 + 2|x| ulp; `log`: 3 ulp outside [0.5, 2], absolute 2^-21 inside; `sin`
//!   and `cos`: absolute 2^-11 on [-pi, pi]; `atan2`: 4096 ulp; `sqrt`: 1 / inverseSqrt
//!   (inverseSqrt within 2 ulp). Outside those domains: anything.
//! - Double precision: "at least that of single precision". [`Emu64`] keeps f64 storage and
//!   range but rounds each result to a 24-bit significand (either neighbour).
//! - Negation and `abs` flip or clear the sign bit: exact.
//!
//! The elementary functions are those of the certified shader (`cb_dev_*`): the f32
//! built-ins, sin and cos after the shader's reduction to [-pi, pi] (emulated operation by
//! operation); [`Emu64`]'s convert the argument to f32 first (GLSL.std.450 defines no f64
//! exp, log, sin, cos or atan2).
//!
//! Each thread draws from its own stream; [`seed`] restarts the calling thread's stream and
//! picks its rounding habit from the seed: each result's side at random, or every result
//! toward zero, or every result away from zero (errors that add up instead of cancelling).
//! The emulated types implement [`DeviceReal`], so every generic twin of a shader (the
//! certificate, Gauss-Jordan, the certified values) runs on them as the device would.

use std::cell::Cell;

use crate::expr::certified::{DeviceReal, DEVICE_F64_UNIT, U32, U64};

thread_local! {
    static STREAM: Cell<u64> = const { Cell::new(0x853c_49e6_748f_ea9b) };
    static HABIT: Cell<Habit> = const { Cell::new(Habit::Random) };
    /// The last multiplication's rounded result (its bits) and exact product (value and
    /// error term), for a following addition to fuse with.
    static PRODUCT: Cell<Option<(u64, f64, f64)>> = const { Cell::new(None) };
}

/// The exact sum of `x` and `y` as `(value, error)`, where `y` may be the previous
/// multiplication's result: then, half the time, the product before its rounding (a fused
/// multiply-add). `y_sign` is -1 for a subtraction.
fn fused_sum(x: f64, y: f64, y_sign: f64) -> (f64, f64) {
    let last = PRODUCT.with(|p| p.take());
    match last {
        Some((bits, p, err)) if y.to_bits() == bits && coin() => {
            let (s, e) = sum(x, y_sign * p);
            (s, e + y_sign * err)
        }
        _ => sum(x, y_sign * y),
    }
}

/// Which side of the exact result a stream rounds to.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Habit {
    Random,
    TowardZero,
    AwayFromZero,
}

/// Restarts the calling thread's stream of adversarial choices at `s`; its habit is
/// `s % 3`: random sides, toward zero, away from zero.
pub fn seed(s: u64) {
    STREAM.with(|c| c.set(s ^ 0x853c_49e6_748f_ea9b));
    let habit = [Habit::Random, Habit::TowardZero, Habit::AwayFromZero][(s % 3) as usize];
    HABIT.with(|h| h.set(habit));
}

/// Whether to move the result of exact value x up (else down), by the stream's habit.
fn upward(x: f64) -> bool {
    match HABIT.with(|h| h.get()) {
        Habit::Random => coin(),
        Habit::TowardZero => x < 0.0,
        Habit::AwayFromZero => x > 0.0,
    }
}

/// The next 64 random bits of this thread's stream (splitmix64).
fn bits() -> u64 {
    STREAM.with(|c| {
        let s = c.get().wrapping_add(0x9e37_79b9_7f4a_7c15);
        c.set(s);
        let mut z = s;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    })
}

fn coin() -> bool {
    bits() & 1 == 1
}

/// A fraction in [0, 1): half the time within 2^-20 of 1 (the edge of what is allowed),
/// else uniform.
fn extent() -> f64 {
    let u = (bits() >> 11) as f64 * 2f64.powi(-53);
    if coin() {
        1.0 - u * 2f64.powi(-20)
    } else {
        u
    }
}

/// ±1 at random.
fn sign() -> f64 {
    if coin() {
        1.0
    } else {
        -1.0
    }
}

/// One ulp of f32 at x (finite, not NaN): 2^(e - 23) for |x| in [2^e, 2^(e+1)), the
/// subnormal spacing 2^-149 below f32's normal range.
fn ulp32(x: f64) -> f64 {
    let e = ((x.to_bits() >> 52) & 0x7ff) as i32 - 1023;
    pow2((e - 23).max(-149))
}

/// A value arbitrary enough to break any code that trusted it.
fn anything(x: f64) -> f64 {
    match bits() % 4 {
        0 => f64::NAN,
        1 => x * 2f64.powi((bits() % 16) as i32 - 8),
        2 => -x,
        _ => 0.0,
    }
}

/// A subnormal operand of the format with smallest normal `min` flushed to zero, half the
/// time.
fn operand(x: f64, min: f64) -> f64 {
    if x != 0.0 && x.abs() < min && coin() {
        0.0f64.copysign(x)
    } else {
        x
    }
}

/// The f32 next to v, above it if `up` (v itself at the infinity in that direction).
fn next32(v: f32, up: bool) -> f32 {
    if v.is_nan() || (v.is_infinite() && (v > 0.0) == up) {
        return v;
    }
    if v == 0.0 {
        let t = f32::from_bits(1);
        return if up { t } else { -t };
    }
    let b = v.to_bits();
    f32::from_bits(if (v > 0.0) == up { b + 1 } else { b - 1 })
}

/// The exact value of an operation as `(x, err)`: x its f64 rounding, err what that left
/// out (exactly: TwoSum and TwoProduct), so that a result rounded "toward zero" from an
/// exact value that f64 rounded onto a representable one still moves.
fn sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    if !s.is_finite() {
        return (s, 0.0);
    }
    let bb = s - a;
    (s, (a - (s - bb)) + (b - bb))
}

fn product(a: f64, b: f64) -> (f64, f64) {
    let p = a * b;
    if !p.is_finite() {
        return (p, 0.0);
    }
    (p, a.mul_add(b, -p))
}

/// An f32 result for the exact value x + err: itself where f32 holds it, else either f32
/// neighbour; a subnormal flushed half the time.
fn round32(x: f64, err: f64) -> f32 {
    if x.is_nan() {
        return f32::NAN;
    }
    let near = x as f32;
    let r = if near as f64 == x && err == 0.0 {
        near
    } else {
        let above = if near as f64 == x {
            err > 0.0
        } else {
            (near as f64) < x
        };
        let (lo, hi) = if above {
            (near, next32(near, true))
        } else {
            (next32(near, false), near)
        };
        if upward(x) {
            hi
        } else {
            lo
        }
    };
    if r != 0.0 && r.abs() < f32::MIN_POSITIVE && coin() {
        0.0f32.copysign(r)
    } else {
        r
    }
}

/// One ulp of a 24-bit significand at x in f64's exponent range: single precision's
/// relative spacing, 2^(e - 23) for |x| in [2^e, 2^(e+1)).
fn ulp_single(x: f64) -> f64 {
    let e = ((x.to_bits() >> 52) & 0x7ff) as i32 - 1023;
    pow2((e - 23).max(-1074))
}

/// 2^k for k in -1074..=1023, exactly (powi underflows below about 2^-1022).
fn pow2(k: i32) -> f64 {
    if k >= -1022 {
        f64::from_bits(((k + 1023) as u64) << 52)
    } else {
        f64::from_bits(1u64 << (k + 1074))
    }
}

/// The distance from x, a value with a 24-bit significand, to the next one up (`up`) or
/// down: half the spacing toward zero from a power of two.
fn grid_step(x: f64, up: bool) -> f64 {
    if (x > 0.0) == up || x == 0.0 {
        ulp_single(x)
    } else {
        ulp_single(x * (1.0 - 2f64.powi(-30)))
    }
}

/// An f64 result for the exact value x + err at single precision: x itself where a 24-bit
/// significand holds it exactly, else either neighbour with a 24-bit significand (in f64's
/// exponent range); a subnormal flushed half the time.
fn round64(x: f64, err: f64) -> f64 {
    if !x.is_finite() {
        return x;
    }
    let m = ulp_single(x);
    let lo = (x / m).floor() * m;
    let (lo, hi) = if lo != x {
        (lo, lo + m)
    } else if err == 0.0 {
        (x, x)
    } else if err > 0.0 {
        (x, x + grid_step(x, true))
    } else {
        (x - grid_step(x, false), x)
    };
    let r = if upward(x) { hi } else { lo };
    if r != 0.0 && r.abs() < f64::MIN_POSITIVE && coin() {
        0.0f64.copysign(r)
    } else {
        r
    }
}

/// A value within `err` of x, but for a choice of the stream: x + t err, |t| < 1.
fn within(x: f64, err: f64) -> f64 {
    x + sign() * extent() * err * (1.0 - 2f64.powi(-20))
}

/// The specifications' bounds on the built-in functions, as a distance from the exact value
/// at x (exact value y), or None where they promise nothing.
mod spec {
    use std::f64::consts::PI;

    pub fn div(q: f64, y: f64, ulp: f64) -> Option<f64> {
        let a = y.abs();
        (a >= 2f64.powi(-126) && a <= 2f64.powi(126) && q.is_finite()).then_some(2.5 * ulp)
    }
    pub fn exp(x: f64, y: f64, ulp: f64) -> Option<f64> {
        (x.abs() <= 88.0).then_some((3.0 + 2.0 * x.abs()) * ulp.max(super::ulp32(y)))
    }
    pub fn ln(x: f64, y: f64, ulp: f64) -> Option<f64> {
        if !(x >= 2f64.powi(-126) && x.is_finite()) {
            None
        } else if (0.5..=2.0).contains(&x) {
            Some(2f64.powi(-21))
        } else {
            Some(3.0 * ulp.max(super::ulp32(y)))
        }
    }
    pub fn trig(x: f64) -> Option<f64> {
        (x.abs() <= PI).then_some(2f64.powi(-11))
    }
    pub fn atan2(y: f64, x: f64, r: f64) -> Option<f64> {
        (x.is_finite() && y.is_finite() && (x != 0.0 || y != 0.0))
            .then_some(4096.0 * super::ulp32(r))
    }
}

/// The f32 built-ins as the certified shader calls them (`cb_dev_*`), on emulated f32
/// arguments.
mod builtin {
    use super::{spec, Emu32};
    use crate::expr::certified::DeviceReal;

    fn near(x: f64, err: Option<f64>) -> Emu32 {
        Emu32::near(x, err)
    }

    pub fn exp(x: Emu32) -> Emu32 {
        let x = x.op();
        let y = x.exp();
        near(y, spec::exp(x, y, 0.0))
    }

    pub fn ln(x: Emu32) -> Emu32 {
        let x = x.op();
        let y = x.ln();
        near(y, spec::ln(x, y, 0.0))
    }

    /// `cb_reduce` (x - 2 pi n in emulated f32 operations, clamped to [-pi, pi]), then the
    /// built-in.
    pub fn trig(x: Emu32, cos: bool) -> Emu32 {
        let c = |v: f64| Emu32(v as f32);
        let lo = (std::f64::consts::TAU - 6.28125) as f32 as f64;
        let n = c((x.mul(c(0.15915494)).0 as f64).round());
        let r = x.sub(n.mul(c(6.28125))).sub(n.mul(c(lo)));
        let r = (r.0 as f64).clamp(-3.1415925, 3.1415925);
        let r = (r as f32) as f64;
        let y = if cos { r.cos() } else { r.sin() };
        near(y, spec::trig(r))
    }

    pub fn atan2(y: Emu32, x: Emu32) -> Emu32 {
        let (y, x) = (y.op(), x.op());
        let r = y.atan2(x);
        near(r, spec::atan2(y, x, r))
    }
}

macro_rules! emulated {
    ($name:ident, $t:ty, $unit:expr, $spec:expr, $min:expr, $round:ident, $ulp:ident, $doc:literal) => {
        #[doc = $doc]
        #[derive(Clone, Copy, Debug)]
        pub struct $name(pub $t);

        /// A comparison of the operands as the device sees them: each subnormal flushed
        /// to zero half the time.
        impl PartialEq for $name {
            fn eq(&self, other: &Self) -> bool {
                self.op() == other.op()
            }
        }

        impl PartialOrd for $name {
            fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
                self.op().partial_cmp(&other.op())
            }
        }

        impl $name {
            fn op(self) -> f64 {
                operand(self.0 as f64, $min)
            }
            /// The value as the f32 a built-in function takes (a conversion, either
            /// neighbour, for f64).
            fn to32(self) -> Emu32 {
                Emu32(round32(self.op(), 0.0))
            }
            fn out((x, err): (f64, f64)) -> Self {
                $name($round(x, err))
            }
            /// A result within `err` of the exact x (or anything where err is None),
            /// rounded to the type toward x; a subnormal flushed half the time.
            fn near(x: f64, err: Option<f64>) -> Self {
                let v = match err {
                    Some(e) if x.is_finite() => within(x, e),
                    _ => anything(x),
                };
                let mut r = v as $t;
                if r != 0.0 && (r as f64 - x).abs() > (v - x).abs() {
                    r = <$t>::from_bits(if (r as f64 > x) == (r > 0.0) {
                        r.to_bits() - 1
                    } else {
                        r.to_bits() + 1
                    });
                }
                if r != 0.0 && (r.abs() as f64) < $min && coin() {
                    r = 0.0;
                }
                $name(r)
            }
        }

        impl DeviceReal for $name {
            fn of(x: f64) -> Self {
                $name(<$t as DeviceReal>::of(x))
            }
            fn wide(self) -> f64 {
                self.0 as f64
            }
            fn of_up(x: f64) -> Self {
                $name(<$t as DeviceReal>::of_up(x))
            }
            const UNIT: f64 = $unit;
            const SPEC_UNIT: f64 = $spec;
            const MIN_NORMAL: f64 = $min;
            fn add(self, b: Self) -> Self {
                Self::out(fused_sum(self.op(), b.op(), 1.0))
            }
            fn sub(self, b: Self) -> Self {
                Self::out(fused_sum(self.op(), b.op(), -1.0))
            }
            fn mul(self, b: Self) -> Self {
                let (p, err) = product(self.op(), b.op());
                let r = Self::out((p, err));
                PRODUCT.with(|c| c.set(Some(((r.0 as f64).to_bits(), p, err))));
                r
            }
            fn div(self, b: Self) -> Self {
                let (x, y) = (self.op(), b.op());
                let q = x / y;
                Self::near(q, spec::div(q, y, $ulp(q)))
            }
            fn abs(self) -> Self {
                $name(self.0.abs())
            }
            fn neg(self) -> Self {
                $name(-self.0)
            }
            fn sqrt(self) -> Self {
                // 1 / inverseSqrt(x), inverseSqrt within 2 ulp.
                let x = self.op();
                let r = 1.0 / x.sqrt();
                let is = if x > 0.0 && r.is_finite() {
                    Self::near(r, Some(2.0 * $ulp(r)))
                } else {
                    Self::near(r, None)
                };
                Self::of(1.0).div(is)
            }
            fn exp(self) -> Self {
                $name(builtin::exp(self.to32()).0 as $t)
            }
            fn ln(self) -> Self {
                $name(builtin::ln(self.to32()).0 as $t)
            }
            fn sin(self) -> Self {
                $name(builtin::trig(self.to32(), false).0 as $t)
            }
            fn cos(self) -> Self {
                $name(builtin::trig(self.to32(), true).0 as $t)
            }
            fn atan2(self, b: Self) -> Self {
                $name(builtin::atan2(self.to32(), b.to32()).0 as $t)
            }
        }
    };
}

emulated!(
    Emu32,
    f32,
    U32,
    U32,
    f32::MIN_POSITIVE as f64,
    round32,
    ulp32,
    "An f32 of an emulated conforming device: each operation as the specifications allow \
     (module docs)."
);
emulated!(
    Emu64,
    f64,
    U64,
    DEVICE_F64_UNIT,
    f64::MIN_POSITIVE,
    round64,
    ulp_single,
    "An f64 of an emulated conforming device: f64 storage and range, each operation with \
     the error single precision allows (module docs); its `SPEC_UNIT` is [`DEVICE_F64_UNIT`]."
);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn f32_operations_stay_within_one_ulp_and_take_both_sides() {
        seed(0);
        let (mut below, mut above) = (0, 0);
        for i in 0..10_000 {
            let a = 1.0f32 + i as f32 * 1e-3;
            let b = 3.0f32 / (i as f32 + 7.0);
            let exact = a as f64 * b as f64;
            let got = Emu32(a).mul(Emu32(b)).0 as f64;
            assert!((got - exact).abs() < ulp32(exact), "{a} * {b}");
            below += (got < exact) as usize;
            above += (got > exact) as usize;
        }
        assert!(below > 1_000 && above > 1_000, "{below} {above}");
    }

    #[test]
    fn f64_operations_err_by_up_to_an_f32_ulp() {
        seed(2);
        let mut worst: f64 = 0.0;
        for i in 0..10_000 {
            let (a, b) = (1.0 + i as f64 * 1e-4, 0.1 + i as f64);
            // a + b to within f64's rounding: the result is within one ulp of it (and under
            // one of the exact sum).
            let exact = a + b;
            let got = Emu64(a).add(Emu64(b)).0;
            let rel = (got - exact).abs() / ulp_single(exact);
            assert!(rel <= 1.0, "{a} + {b}: {rel} ulp");
            worst = worst.max(rel);
        }
        // Far beyond f64's own rounding: the freedom the specifications leave is used.
        assert!(worst > 0.9, "{worst}");
    }

    #[test]
    fn subnormals_are_flushed_sometimes() {
        seed(3);
        let tiny = f32::MIN_POSITIVE / 4.0;
        let flushed = (0..200)
            .filter(|_| Emu32(tiny).add(Emu32(0.0)).0 == 0.0)
            .count();
        assert!(flushed > 20 && flushed < 180, "{flushed}");
    }

    #[test]
    fn comparisons_flush_subnormal_operands_sometimes() {
        seed(5);
        let (tiny, zero) = (Emu32(f32::MIN_POSITIVE / 4.0), Emu32(0.0));
        let as_zero = (0..200).filter(|_| tiny <= zero).count();
        assert!(as_zero > 20 && as_zero < 180, "{as_zero}");
        let tiny = Emu64(f64::MIN_POSITIVE / 4.0);
        let equal = (0..200).filter(|_| tiny == Emu64(0.0)).count();
        assert!(equal > 20 && equal < 180, "{equal}");
        // A normal value compares as itself.
        assert!((0..200).all(|_| Emu32(f32::MIN_POSITIVE) > zero));
    }

    #[test]
    fn division_outside_its_range_promises_nothing() {
        seed(4);
        let odd = (0..100)
            .filter(|_| {
                let q = Emu32(1.0).div(Emu32(f32::MAX)).0;
                !(0.0..1e-37).contains(&q)
            })
            .count();
        assert!(odd > 0);
        for i in 1..1000 {
            let (x, y) = (i as f32, 7.0f32);
            let (q, exact) = (Emu32(x).div(Emu32(y)).0 as f64, x as f64 / 7.0);
            assert!((q - exact).abs() <= 2.5 * ulp32(exact));
        }
    }

    #[test]
    fn multiply_adds_are_fused_sometimes() {
        // (1 + 2^-12)^2 - (1 + 2^-11) is 2^-24 exactly; rounding the product first gives 0
        // or 2^-23.
        seed(0);
        let a = Emu32(1.0 + 2f32.powi(-12));
        let c = Emu32(1.0 + 2f32.powi(-11));
        let (mut fused, mut split) = (0, 0);
        for _ in 0..400 {
            let r = c.neg().add(a.mul(a)).0;
            if r == 2f32.powi(-24) {
                fused += 1;
            } else {
                assert!(r == 0.0 || r == 2f32.powi(-23), "{r}");
                split += 1;
            }
        }
        assert!(fused > 50 && split > 50, "{fused} {split}");
    }

    #[test]
    fn streams_are_deterministic() {
        let run = || {
            seed(9);
            (0..100)
                .map(|i| Emu64(i as f64 + 0.1).mul(Emu64(0.3)).0.to_bits())
                .collect::<Vec<_>>()
        };
        assert_eq!(run(), run());
    }
}
