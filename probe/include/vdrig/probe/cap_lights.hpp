// A light spread over a cap instead of a point: the kernel of the lights of hybrid:N and soft:N (docs/probe.md,
// "Irradiance maps").
//
// A directional light carrying the power P of a region of the map, placed at the region's luminance centroid d,
// gives P max(0, n . d). That is wrong twice for a broad region: the region's mean direction m = integral of L w dw / P
// is shorter than 1, so a normal facing it gets P n . m, not P n . d (up to 1.6 % too much for the 0.2 sr regions of
// 64 lights: 1 - |m| of a uniform region that size); and a normal whose horizon cuts the region still sees part of it,
// where the point is all or nothing. A uniform cap of half-angle a centred on d has mean direction (1 + cos a) / 2 d,
// so the cap with |m| = (1 + cos a) / 2 has the region's first moment exactly, and its clamped-cosine integral (closed
// form, Snyder 1996) fades through the horizon as the region does.
#pragma once

namespace vdrig::probe {

/// The cosine of the half-angle a of the uniform cap whose mean direction has length `mean_length`: 2 |m| - 1,
/// clamped to a in [0, 88 deg] (the closed form below needs a < 90 deg; |m| <= 0.5 only comes from a region spread
/// over a hemisphere or more), and 1 (a point) within 5e-9 of it. The lights carry the cosine, not the angle, so
/// that evaluating them needs no trigonometry off the horizon.
double cap_cos_half_angle_for_mean_length(double mean_length);

/// (1 / solid angle of the cap) x integral over the cap of max(0, n . w) dw, for a cap of half-angle a (cosine
/// `cos_half_angle`, a clamped to <= 88 deg) centred on d, t = n . d: what a light of power 1 spread uniformly over
/// the cap gives a normal n. max(0, t) for a point (cos a = 1); (1 + cos a) / 2 t when the cap lies wholly above
/// n's horizon.
double cap_clamped_cosine(double t, double cos_half_angle);

/// The SH-9 band limit of cap_clamped_cosine: sum over l = 0..2 of A_l (2 l + 1) / (4 pi) c_l P_l(t), with the
/// cap's Legendre moments c_0 = 1, c_1 = (1 + cos a) / 2, c_2 = cos a (1 + cos a) / 2 (sh9_clamped_cosine for a = 0).
double cap_sh9_clamped_cosine(double t, double cos_half_angle);

}  // namespace vdrig::probe
