//! ΔT = TT − UT1 in seconds, estimated from the date when the user gives none.
//!
//! Espenak & Meeus, "Five Millennium Canon of Solar Eclipses: −1999 to +3000" (NASA/TP-2006-
//! 214141), polynomial expressions for ΔT, as published at
//! <https://eclipse.gsfc.nasa.gov/SEhelp/deltatpoly2004.html>. The decimal year is
//! `y = year + (month − 0.5)/12`; the branch is chosen by the integer year. Beyond +3000 (up to
//! SPA's limit of 6000) the canon's long-term parabola `−20 + 32·u²` is used, as the page
//! advises for dates outside the tabulated range. Measured ΔT is known only since the 17th
//! century; earlier and later values are extrapolations with uncertainties of minutes to hours.

use super::time::CivilTime;

/// ΔT in seconds for a calendar year and month (1–12).
pub fn espenak_meeus(year: i64, month: u32) -> f64 {
    let y = year as f64 + (f64::from(month) - 0.5) / 12.0;
    let poly = |x: f64, c: &[f64]| c.iter().rev().fold(0.0, |acc, &k| acc * x + k);
    let long_term = |y: f64| {
        let u = (y - 1820.0) / 100.0;
        -20.0 + 32.0 * u * u
    };
    match year {
        ..-500 => long_term(y),
        -500..500 => poly(y / 100.0, &[10583.6, -1014.41, 33.78311, -5.952053, -0.1798452, 0.022174192, 0.0090316521]),
        500..1600 => poly((y - 1000.0) / 100.0, &[1574.2, -556.01, 71.23472, 0.319781, -0.8503463, -0.005050998, 0.0083572073]),
        1600..1700 => poly(y - 1600.0, &[120.0, -0.9808, -0.01532, 1.0 / 7129.0]),
        1700..1800 => poly(y - 1700.0, &[8.83, 0.1603, -0.0059285, 0.00013336, -1.0 / 1_174_000.0]),
        1800..1860 => poly(y - 1800.0, &[13.72, -0.332447, 0.0068612, 0.0041116, -0.00037436, 0.0000121272, -0.0000001699, 0.000000000875]),
        1860..1900 => poly(y - 1860.0, &[7.62, 0.5737, -0.251754, 0.01680668, -0.0004473624, 1.0 / 233_174.0]),
        1900..1920 => poly(y - 1900.0, &[-2.79, 1.494119, -0.0598939, 0.0061966, -0.000197]),
        1920..1941 => poly(y - 1920.0, &[21.20, 0.84493, -0.076100, 0.0020936]),
        1941..1961 => poly(y - 1950.0, &[29.07, 0.407, -1.0 / 233.0, 1.0 / 2547.0]),
        1961..1986 => poly(y - 1975.0, &[45.45, 1.067, -1.0 / 260.0, -1.0 / 718.0]),
        1986..2005 => poly(y - 2000.0, &[63.86, 0.3345, -0.060374, 0.0017275, 0.000651814, 0.00002373599]),
        2005..2050 => poly(y - 2000.0, &[62.92, 0.32217, 0.005589]),
        2050..2150 => long_term(y) - 0.5628 * (2150.0 - y),
        _ => long_term(y),
    }
}

/// ΔT for the calendar month of an instant.
pub fn for_civil(c: &CivilTime) -> f64 {
    espenak_meeus(c.year, c.month)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_the_canon_and_observed_values() {
        // Espenak & Meeus's own table of ΔT (same page): 1900: −2.7 s, 1950: 29.1 s,
        // 2000: 63.8 s, 1700: 9 s (rounded). Mid-year = month 7 (y = year + 0.54).
        assert!((espenak_meeus(1900, 1) - (-2.7)).abs() < 0.3);
        assert!((espenak_meeus(1950, 1) - 29.1).abs() < 0.3);
        assert!((espenak_meeus(2000, 1) - 63.8).abs() < 0.2);
        assert!((espenak_meeus(1700, 1) - 9.0).abs() < 0.5);
        // Observed ΔT (IERS): 2003.8 ≈ 64.6 s (the SPA test case uses 67 s, its own assumption).
        assert!((espenak_meeus(2003, 10) - 64.6).abs() < 0.5);
    }

    #[test]
    fn agrees_with_pvlib_calculate_deltat() {
        // pvlib 0.16.1 pvlib.spa.calculate_deltat(year, month), an independent implementation
        // of the same polynomials (printed with `python3 -c 'from pvlib import spa; print(spa.calculate_deltat(y, m))'`).
        let cases = [
            (-1999, 6, 46_640.033_472_222_225),
            (-600, 1, 18_719.834_672_222_227),
            (0, 3, 10_581.486_792_407_592),
            (1000, 12, 1_568.878_113_324_083_6),
            (1650, 7, 49.404_472_307_930_98),
            (1850, 2, 7.122_392_718_457_945),
            (2003, 10, 64.507_826_275_740_74),
            (2100, 1, 202.838_122_222_221_9),
            (3000, 12, 4_442.920_272_222_223),
            (6000, 6, 55_903.942_005_555_55),
        ];
        for (year, month, want) in cases {
            let got = espenak_meeus(year, month);
            assert!((got - want).abs() < 1e-6 * want.abs().max(1.0), "{year}-{month}: {got} vs {want}");
        }
    }
}
