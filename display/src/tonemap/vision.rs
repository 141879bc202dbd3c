//! Human vision models the "human" tone mapping needs: contrast thresholds
//! (Ferwerda et al. 1996, as in Radiance's `pcond`) and the loss of colour
//! sensitivity in mesopic and scotopic light.

/// Rec. 709 luminance weights for linear RGB; the renderer's primaries.
pub(crate) const LUMINANCE_WEIGHTS: [f64; 3] = [0.2126, 0.7152, 0.0722];

/// Below this world luminance (cd/m²) only rods see: no colour at all.
pub const BOTTOM_MESOPIC: f64 = 5.62e-3;

/// Above this world luminance (cd/m²) cones see fully: colour unchanged.
pub const TOP_MESOPIC: f64 = 5.62;

/// Photopic luminance of linear RGB, in the units of the input.
pub(crate) fn luminance(c: [f64; 3]) -> f64 {
    LUMINANCE_WEIGHTS[0] * c[0] + LUMINANCE_WEIGHTS[1] * c[1] + LUMINANCE_WEIGHTS[2] * c[2]
}

/// The threshold-versus-intensity function ΔL_t(L_a): the smallest luminance
/// difference (cd/m²) visible against an adapting luminance `la` (cd/m²).
///
/// The piecewise log-log fit of Ferwerda, Pattanaik, Shirley & Greenberg
/// (SIGGRAPH 96), rods below about 0.04 cd/m² and cones above, with the same
/// constants and the same floor below 1.148e-4 cd/m² as Radiance's `pcond`,
/// which is what Ward Larson et al. (1997) used for the human ceiling. The
/// fit steps down a little at two of its joins (2.8 % at log L_a = −1.44,
/// 0.7 % at 1.9); it is kept as published, since it only sets a ceiling.
pub fn threshold_versus_intensity(la: f64) -> f64 {
    if la.is_nan() || la < 1.148e-4 {
        return 1.38e-3;
    }
    let l = la.log10();
    let log_dl = if l < -1.44 {
        (0.405 * l + 1.6).powf(2.18) - 2.86
    } else if l < -0.0184 {
        l - 0.395
    } else if l < 1.9 {
        (0.249 * l + 0.65).powf(2.7) - 0.72
    } else {
        l - 1.255
    };
    10f64.powf(log_dl)
}

/// Unnormalised scotopic luminance: Y_s = Y (1.33 (1 + (Y + Z) / X) − 1.68),
/// the approximation `pcond` uses, with X, Y, Z from Rec. 709 primaries.
fn scotopic_raw(c: [f64; 3]) -> f64 {
    let x = 0.4124 * c[0] + 0.3576 * c[1] + 0.1805 * c[2];
    let y = luminance(c);
    let z = 0.0193 * c[0] + 0.1192 * c[1] + 0.9505 * c[2];
    if x <= 0.0 || y <= 0.0 {
        return 0.0;
    }
    (y * (1.33 * (1.0 + (y + z) / x) - 1.68)).max(0.0)
}

/// Scotopic luminance scaled so that RGB white keeps its photopic luminance:
/// without it, night scenes would jump in brightness by the scotopic/photopic
/// efficacy ratio (about 2.6 for our white; `pcond` divides by a fixed 2.26
/// for Radiance's equal-energy white).
pub fn scotopic_luminance(c: [f64; 3]) -> f64 {
    let white = scotopic_raw([1.0; 3]) / luminance([1.0; 3]);
    scotopic_raw(c) / white
}

/// How much cone (colour) vision is left at world luminance `lw` (cd/m²):
/// 0 at and below [`BOTTOM_MESOPIC`], 1 at and above [`TOP_MESOPIC`].
///
/// `pcond` blends linearly in luminance; we blend linearly in log luminance.
/// With the linear blend a saturated blue that brightens through the top of
/// the mesopic band gets *darker* on the display (its scotopic luminance is
/// 2.8 times its photopic one and the blend moves away from it too fast); in
/// log luminance the blend is slow enough that brighter world is never
/// dimmer display for any non-negative RGB.
pub fn cone_fraction(lw: f64) -> f64 {
    if lw.is_nan() || lw <= BOTTOM_MESOPIC {
        return 0.0;
    }
    if lw >= TOP_MESOPIC {
        return 1.0;
    }
    (lw / BOTTOM_MESOPIC).log10() / (TOP_MESOPIC / BOTTOM_MESOPIC).log10()
}

/// The colour a viewer adapted to the pixel's own level would see: a blend
/// of the colour and the grey of its scotopic luminance. `lw` is the pixel's
/// photopic luminance in cd/m²; `c` is in any linear unit.
pub fn mesopic_color(c: [f64; 3], lw: f64) -> [f64; 3] {
    let k = cone_fraction(lw);
    if k >= 1.0 {
        return c;
    }
    let grey = (1.0 - k) * scotopic_luminance(c);
    [k * c[0] + grey, k * c[1] + grey, k * c[2] + grey]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tvi_is_continuous_and_increasing() {
        let mut prev = threshold_versus_intensity(1e-6);
        let mut b = -6.0;
        while b < 8.0 {
            b += 0.001;
            let t = threshold_versus_intensity(10f64.powf(b));
            // The published fit steps down a little at two branch joins.
            let step_down = if (b + 1.44).abs() < 0.002 || (b - 1.9).abs() < 0.002 {
                0.97
            } else {
                0.999
            };
            assert!(t >= prev * step_down, "TVI drops at log L = {b}");
            assert!((t / prev - 1.0).abs() < 0.03, "TVI jumps at log L = {b}: {prev} -> {t}");
            prev = t;
        }
        // Weber's law in the photopic range: 10^-1.255 ≈ 5.6 % contrast.
        assert!((threshold_versus_intensity(1000.0) / 1000.0 - 0.0556).abs() < 1e-3);
    }

    #[test]
    fn white_keeps_its_luminance_and_red_gets_dark_at_night() {
        assert!((scotopic_luminance([1.0; 3]) - 1.0).abs() < 1e-12);
        assert!((scotopic_luminance([0.5; 3]) - 0.5).abs() < 1e-12);
        // The Purkinje shift: red looks much darker, blue brighter to rods.
        assert!(scotopic_luminance([1.0, 0.0, 0.0]) < 0.25 * luminance([1.0, 0.0, 0.0]));
        assert!(scotopic_luminance([0.0, 0.0, 1.0]) > 2.0 * luminance([0.0, 0.0, 1.0]));
        assert_eq!(scotopic_luminance([0.0; 3]), 0.0);
    }

    #[test]
    fn mesopic_blend_is_grey_below_and_unchanged_above() {
        let red = [1.0, 0.0, 0.0];
        let night = mesopic_color(red, 1e-3);
        assert_eq!(night[0], night[1]);
        assert_eq!(night[1], night[2]);
        assert_eq!(mesopic_color(red, 10.0), red);
        let dusk = mesopic_color(red, 0.1);
        assert!(dusk[0] > dusk[1] && dusk[1] > 0.0);
    }

    #[test]
    fn mesopic_luminance_never_falls_as_the_world_brightens() {
        for c in [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 1.0], [0.3, 0.1, 0.9]] {
            let y = luminance(c);
            let mut prev = 0.0;
            let mut b = -4.0;
            while b < 2.0 {
                let lw = 10f64.powf(b);
                let shown = luminance(mesopic_color(c.map(|v| v * lw / y), lw));
                assert!(shown >= prev, "{c:?} at {lw}: {shown} < {prev}");
                prev = shown;
                b += 0.01;
            }
        }
    }
}
