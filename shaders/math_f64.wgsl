// f64 elementary functions. SPIR-V's GLSL.std.450 offers sqrt, abs, sign, min, max, floor and
// ldexp on f64 but no exp, log, trigonometric or hyperbolic functions: these are built from
// range reduction and polynomials (exp, sin, cos), or from an f32 first guess refined by
// Newton steps in f64 (log, atan, atan2). Accurate to a few ulps within f32's exponent range.

const M64_LN2_HI: f64 = 0.6931471803691238lf;
const M64_LN2_LO: f64 = 1.9082149292705877e-10lf;
const M64_INV_LN2: f64 = 1.4426950408889634lf;
const M64_PIO2_HI: f64 = 1.5707963267341256lf;
const M64_PIO2_LO: f64 = 6.077100506506192e-11lf;
const M64_TWO_OVER_PI: f64 = 0.6366197723675814lf;

fn m64_exp(x: f64) -> f64 {
    if (x > 709.0lf) {
        return x * 1.0e308lf;
    }
    if (x < -745.0lf) {
        return 0.0lf;
    }
    let n = floor(x * M64_INV_LN2 + 0.5lf);
    let r = (x - n * M64_LN2_HI) - n * M64_LN2_LO;
    // Taylor series to r^13 / 13!, |r| <= 0.35.
    var p = 1.0lf / 6227020800.0lf;
    p = p * r + 1.0lf / 479001600.0lf;
    p = p * r + 1.0lf / 39916800.0lf;
    p = p * r + 1.0lf / 3628800.0lf;
    p = p * r + 1.0lf / 362880.0lf;
    p = p * r + 1.0lf / 40320.0lf;
    p = p * r + 1.0lf / 5040.0lf;
    p = p * r + 1.0lf / 720.0lf;
    p = p * r + 1.0lf / 120.0lf;
    p = p * r + 1.0lf / 24.0lf;
    p = p * r + 1.0lf / 6.0lf;
    p = p * r + 0.5lf;
    p = p * r + 1.0lf;
    p = p * r + 1.0lf;
    return ldexp(p, i32(n));
}

fn m64_ln(x: f64) -> f64 {
    if (!(x > 0.0lf)) {
        // log(0) = -inf, log(<0) = NaN, at run time.
        return select((x - x) / (x - x), -1.0e308lf * (10.0lf - x), x == 0.0lf);
    }
    var y = f64(log(f32(x)));
    y = y - 1.0lf + x * m64_exp(-y);
    y = y - 1.0lf + x * m64_exp(-y);
    return y;
}

// sin and cos of r for |r| <= pi/4.
fn m64_sin_poly(r: f64) -> f64 {
    let r2 = r * r;
    var p = -1.0lf / 1307674368000.0lf;
    p = p * r2 + 1.0lf / 6227020800.0lf;
    p = p * r2 - 1.0lf / 39916800.0lf;
    p = p * r2 + 1.0lf / 362880.0lf;
    p = p * r2 - 1.0lf / 5040.0lf;
    p = p * r2 + 1.0lf / 120.0lf;
    p = p * r2 - 1.0lf / 6.0lf;
    return r + r * r2 * p;
}

fn m64_cos_poly(r: f64) -> f64 {
    let r2 = r * r;
    var p = 1.0lf / 20922789888000.0lf;
    p = p * r2 - 1.0lf / 87178291200.0lf;
    p = p * r2 + 1.0lf / 479001600.0lf;
    p = p * r2 - 1.0lf / 3628800.0lf;
    p = p * r2 + 1.0lf / 40320.0lf;
    p = p * r2 - 1.0lf / 720.0lf;
    p = p * r2 + 1.0lf / 24.0lf;
    p = p * r2 - 0.5lf;
    return 1.0lf + r2 * p;
}

// (sin x, cos x) by reduction modulo pi/2.
fn m64_sincos(x: f64) -> vec2<f64> {
    let k = floor(x * M64_TWO_OVER_PI + 0.5lf);
    let r = (x - k * M64_PIO2_HI) - k * M64_PIO2_LO;
    let s = m64_sin_poly(r);
    let c = m64_cos_poly(r);
    let q = ((i32(k) % 4) + 4) % 4;
    switch q {
        case 0: { return vec2<f64>(s, c); }
        case 1: { return vec2<f64>(c, -s); }
        case 2: { return vec2<f64>(-s, -c); }
        default: { return vec2<f64>(-c, s); }
    }
}

fn m64_sin(x: f64) -> f64 {
    return m64_sincos(x).x;
}

fn m64_cos(x: f64) -> f64 {
    return m64_sincos(x).y;
}

fn m64_tan(x: f64) -> f64 {
    let sc = m64_sincos(x);
    return sc.x / sc.y;
}

// The angle of (x, y): f32 guess, then two Newton steps on the rotation residual.
fn m64_atan2(y: f64, x: f64) -> f64 {
    if (x == 0.0lf && y == 0.0lf) {
        return select(0.0lf, 3.141592653589793lf, x < 0.0lf) * select(1.0lf, -1.0lf, y < 0.0lf);
    }
    var t = f64(atan2(f32(y), f32(x)));
    for (var i = 0; i < 2; i++) {
        let sc = m64_sincos(t);
        t = t + (y * sc.y - x * sc.x) / (x * sc.y + y * sc.x);
    }
    return t;
}

fn m64_atan(x: f64) -> f64 {
    return m64_atan2(x, 1.0lf);
}

fn m64_asin(x: f64) -> f64 {
    return m64_atan2(x, sqrt((1.0lf - x) * (1.0lf + x)));
}

fn m64_acos(x: f64) -> f64 {
    return m64_atan2(sqrt((1.0lf - x) * (1.0lf + x)), x);
}

fn m64_sinh(x: f64) -> f64 {
    if (abs(x) < 0.5lf) {
        let x2 = x * x;
        var p = 1.0lf / 1307674368000.0lf;
        p = p * x2 + 1.0lf / 6227020800.0lf;
        p = p * x2 + 1.0lf / 39916800.0lf;
        p = p * x2 + 1.0lf / 362880.0lf;
        p = p * x2 + 1.0lf / 5040.0lf;
        p = p * x2 + 1.0lf / 120.0lf;
        p = p * x2 + 1.0lf / 6.0lf;
        return x + x * x2 * p;
    }
    let e = m64_exp(x);
    return 0.5lf * (e - 1.0lf / e);
}

fn m64_cosh(x: f64) -> f64 {
    let e = m64_exp(abs(x));
    return 0.5lf * (e + 1.0lf / e);
}

fn m64_tanh(x: f64) -> f64 {
    if (abs(x) < 0.5lf) {
        return m64_sinh(x) / m64_cosh(x);
    }
    if (abs(x) > 20.0lf) {
        return sign(x);
    }
    let e = m64_exp(-2.0lf * abs(x));
    return sign(x) * (1.0lf - e) / (1.0lf + e);
}

fn m64_pow(a: f64, b: f64) -> f64 {
    if (a == 0.0lf) {
        // 0^b: 0 for b > 0, 1 for b = 0, +inf (at run time) for b < 0.
        return select(select(1.0lf, 0.0lf, b > 0.0lf), 1.0e308lf * (10.0lf - a), b < 0.0lf);
    }
    return m64_exp(b * m64_ln(a));
}
