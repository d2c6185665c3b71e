// The third candidate of bmfr's selection (`nlm`, src/filters/bmfr/nlm.rs has the reasons and
// the measurements): non-local means of the albedo-demodulated light (Rousselle, Knaus,
// Zwicker, "Adaptive rendering with non-local means filtering", SIGGRAPH Asia 2012, eq. 4 with
// patches of (2 BMFR_NLM_PATCH + 1)^2 pixels, `nlm_patch`), run on the full image and, for
// the selection's error estimate, on each of the two half buffers (NFOR's cross-filtering,
// Bitterli et al. 2016 §4: a half filtered alone is independent of the other half, so its
// squared distance to the other half estimates its error). Included at the end of
// filters/bmfr.cl; the Rust reference does the same float operations in the same order.
//
// A pixel takes part by its class (bmfr_nlm_class; src/filters/bmfr/nlm.rs `class` has the
// reasons) and averages pixels of its class only: a surface (bmfr_surface, filters/bmfr.cl),
// its light demodulated by the albedo, or an open pixel (sky, or samples that did not all hit
// a surface, with samples in both halves), its light as it is.
#define BMFR_NLM_SURFACE 1.0f
#define BMFR_NLM_OPEN 2.0f

inline float bmfr_nlm_class(__global const FilterVector* f, __global const float4* pos,
                            float4 odd, float spp) {
    if (bmfr_surface(f, pos, odd, spp)) return BMFR_NLM_SURFACE;
    return !bmfr_light(f) && odd.w >= 1.0f && spp - odd.w >= 1.0f ? BMFR_NLM_OPEN : 0.0f;
}

// The class of pixel (x, y) as the non-local means and the selection use it (bmfr_nlm_prep
// writes it for the others): bmfr_nlm_class, and with BMFR_OPEN_MARGIN a surface pixel with an
// open pixel among its eight neighbours counted open. Out of focus a silhouette's partly
// covered pixels form a wide band, and a pixel in it whose few samples all hit the surface
// holds the band's mix in expectation, not the surface's light; among open neighbours it
// found few patches of its class and kept about its own light (src/filters/bmfr/nlm.rs, "Open
// margin").
inline float bmfr_nlm_class_at(__global const FilterVector* fv, __global const float4* positions,
                               __global const float4* odd_halves, int x, int y, uint width,
                               uint height, float spp) {
    uint i = (uint)y * width + (uint)x;
    float class = bmfr_nlm_class(fv + i, positions + i, odd_halves[i], spp);
#if BMFR_OPEN_MARGIN
    if (class == BMFR_NLM_SURFACE) {
        for (int yy = max(y - 1, 0); yy <= min(y + 1, (int)height - 1); ++yy) {
            for (int xx = max(x - 1, 0); xx <= min(x + 1, (int)width - 1); ++xx) {
                uint j = (uint)yy * width + (uint)xx;
                if (bmfr_nlm_class(fv + j, positions + j, odd_halves[j], spp) == BMFR_NLM_OPEN)
                    return BMFR_NLM_OPEN;
            }
        }
    }
#endif
    return class;
}

// What a pixel's light is divided by before the averaging and multiplied by after.
inline float3 bmfr_nlm_modulation(__global const FilterVector* f, float class) {
    return class == BMFR_NLM_OPEN ? (float3)(1.0f) : bmfr_albedo(f);
}

// The even samples' mean from the frame's mean and the odd samples' (the beauty itself when
// there are no even samples).
inline float3 bmfr_even(float3 beauty, float4 odd, float spp) {
    float n_even = spp - odd.w;
    return n_even >= 1.0f ? (spp * beauty - odd.w * odd.xyz) / n_even : beauty;
}

// bmfr_nlm_prep: per pixel of a class, (o - e)^2 n_o n_e / n^2, one sample of the variance of
// the frame's mean per channel (E[(o - e)^2] = s^2 (1/n_o + 1/n_e)), and w = the class
// (bmfr_nlm_class_at); 0 elsewhere.
__kernel void bmfr_nlm_prep(__global const FilterVector* fv,
                            __global const float4* positions,
                            __global const float4* odd_halves,
                            uint width, uint height, float spp,
                            __global float4* raw) {
    int x = get_global_id(0), y = get_global_id(1);
    if (x >= (int)width || y >= (int)height) return;
    uint i = (uint)y * width + (uint)x;
    __global const FilterVector* f = fv + i;
    float4 odd = odd_halves[i];
    float class = bmfr_nlm_class_at(fv, positions, odd_halves, x, y, width, height, spp);
    if (class == 0.0f) {
        raw[i] = (float4)(0.0f);
        return;
    }
    float3 d = odd.xyz - bmfr_even(bmfr_beauty(f), odd, spp);
    raw[i] = (float4)(d * d * (odd.w * (spp - odd.w) / (spp * spp)), class);
}

// The inputs of the non-local means for pixel (x, y): the demodulated frame mean (w: the
// class), odd half and even half, and the variance of the demodulated frame mean: the mean of
// `raw` over the pixels of the 3 x 3 window of the pixel's class (one sample is too noisy to
// normalise a distance by; a pixel of no class takes its surface neighbours', as its taps
// enter their patches), over the modulation squared.
inline void bmfr_nlm_pixel(__global const FilterVector* fv, __global const float4* odd_halves,
                           int x, int y, uint width, uint height, float spp,
                           __global const float4* raw, float4 u[4]) {
    uint i = (uint)y * width + (uint)x;
    __global const FilterVector* f = fv + i;
    float own = raw[i].w;
    float3 al = bmfr_nlm_modulation(f, own);
    float3 beauty = bmfr_beauty(f);
    float4 odd = odd_halves[i];
    float class = own == BMFR_NLM_OPEN ? BMFR_NLM_OPEN : BMFR_NLM_SURFACE;
    float3 sum = (float3)(0.0f);
    float count = 0.0f;
    for (int yy = max(y - 1, 0); yy <= min(y + 1, (int)height - 1); ++yy) {
        for (int xx = max(x - 1, 0); xx <= min(x + 1, (int)width - 1); ++xx) {
            float4 r = raw[(uint)yy * width + (uint)xx];
            if (r.w != class) continue;
            sum += r.xyz;
            count += 1.0f;
        }
    }
    float3 v = count > 0.0f ? sum / count / (al * al) : (float3)(0.0f);
    u[0] = (float4)(beauty / al, raw[i].w);
    u[1] = (float4)(odd.xyz / al, 0.0f);
    u[2] = (float4)(bmfr_even(beauty, odd, spp) / al, 0.0f);
    u[3] = (float4)(v, 0.0f);
}

// bmfr_nlm_inputs: bmfr_nlm_pixel's four float4 per pixel, for bmfr_nlm.
__kernel void bmfr_nlm_inputs(__global const FilterVector* fv,
                              __global const float4* odd_halves,
                              uint width, uint height, float spp,
                              __global const float4* raw,
                              __global float4* nlm_in) {
    int x = get_global_id(0), y = get_global_id(1);
    if (x >= (int)width || y >= (int)height) return;
    float4 u[4];
    bmfr_nlm_pixel(fv, odd_halves, x, y, width, height, spp, raw, u);
    for (int m = 0; m < 4; ++m) nlm_in[4 * ((uint)y * width + (uint)x) + m] = u[m];
}

// The output of a pixel that is not a surface: its frame, odd and even means as they are.
inline void bmfr_nlm_pass_through(__global const FilterVector* f, float4 odd, float spp,
                                  __global float4* out) {
    float3 beauty = bmfr_beauty(f);
    out[0] = (float4)(beauty, 0.0f);
    out[1] = (float4)(odd.xyz, 0.0f);
    out[2] = (float4)(bmfr_even(beauty, odd, spp), 0.0f);
}

// bmfr_nlm: for each pixel p of a class, the weighted mean over the pixels q of its class of the
// (2 BMFR_NLM_RADIUS + 1)^2 window (the halves': (2 BMFR_NLM_ESTIMATE_RADIUS + 1)^2, as they
// only estimate the frame's error), w = exp(-max(0, d^2)), d^2 the mean over the
// (2 BMFR_NLM_PATCH + 1)^2 patch taps t with p + t and q + t inside the image, and over the
// channels, of
//   ((u(p + t) - u(q + t))^2 - (v_a + min(v_a, v_b))) / (eps + k^2 (v_a + v_b))
// for the frame (variance v), and of the same with the variances doubled for each half (a half
// holds half the samples), ε doubled too so that one reciprocal serves the three:
//   (((u(p + t) - u(q + t))^2 / 2 - (v_a + min(v_a, v_b))) / (eps + k^2 (v_a + v_b)),
// then remodulated. The tap distances are summed per patch row left to right, then the rows top
// to bottom.
// Three float4 out per pixel: frame, odd half, even half; a pixel
// of no class gives its inputs back.
//
// Work-groups of BMFR_NLM_TILE^2 pixels. A tap's distance depends only on the pixel a = p + t
// and the offset q - p, so for each offset the group writes the distances of its tile and a
// BMFR_NLM_PATCH border to local memory once and each pixel sums its patch's from there: about
// 1.6 distance evaluations per pixel and offset instead of 25 with 5 x 5 patches (the same
// floats in the same order; an invalid tap adds 0 to the sum and 0 to the count). The tile's
// own inputs are read into local memory once.
#define BMFR_NLM_SIDE (BMFR_NLM_TILE + 2 * BMFR_NLM_PATCH)
#define BMFR_NLM_TAPS (2 * BMFR_NLM_PATCH + 1)
#define BMFR_NLM_LOCAL (BMFR_NLM_SIDE * BMFR_NLM_SIDE)
// Whether offset (dx, dy) lies in the halves' window (they are filtered there only; both
// kernels, bmfr_nlm and bmfr_nlm_packed).
#define BMFR_NLM_ESTIMATING(dx, dy)                                                            \
    ((dx) >= -BMFR_NLM_ESTIMATE_RADIUS && (dx) <= BMFR_NLM_ESTIMATE_RADIUS                     \
     && (dy) >= -BMFR_NLM_ESTIMATE_RADIUS && (dy) <= BMFR_NLM_ESTIMATE_RADIUS)

__kernel __attribute__((reqd_work_group_size(BMFR_NLM_TILE, BMFR_NLM_TILE, 1)))
void bmfr_nlm(__global const FilterVector* fv,
              __global const float4* odd_halves,
              uint width, uint height, float spp,
              __global const float4* nlm_in,
              __global float4* nlm_out) {
    __local float4 tile[BMFR_NLM_LOCAL * 4];
    __local float4 dist[BMFR_NLM_LOCAL];
    int lx = get_local_id(0), ly = get_local_id(1);
    int x = get_global_id(0), y = get_global_id(1);
    int x0 = (int)get_group_id(0) * BMFR_NLM_TILE - BMFR_NLM_PATCH;
    int y0 = (int)get_group_id(1) * BMFR_NLM_TILE - BMFR_NLM_PATCH;
    int w = (int)width, h = (int)height;
    int first = ly * BMFR_NLM_TILE + lx;
    for (int e = first; e < BMFR_NLM_LOCAL; e += BMFR_NLM_TILE * BMFR_NLM_TILE) {
        int ax = x0 + e % BMFR_NLM_SIDE, ay = y0 + e / BMFR_NLM_SIDE;
        bool in = ax >= 0 && ax < w && ay >= 0 && ay < h;
        for (int m = 0; m < 4; ++m)
            tile[4 * e + m] = in ? nlm_in[4 * ((uint)ay * width + (uint)ax) + m] : (float4)(0.0f);
    }
    bool inside = x < w && y < h;
    uint i = inside ? (uint)y * width + (uint)x : 0u;
    float class = inside ? nlm_in[4 * i].w : 0.0f;
    bool active = class != 0.0f;
    float k2 = BMFR_NLM_K * BMFR_NLM_K;
    float3 acc[3] = {(float3)(0.0f), (float3)(0.0f), (float3)(0.0f)};
    float wsum[3] = {0.0f, 0.0f, 0.0f};
    for (int dy = -BMFR_NLM_RADIUS; dy <= BMFR_NLM_RADIUS; ++dy) {
        for (int dx = -BMFR_NLM_RADIUS; dx <= BMFR_NLM_RADIUS; ++dx) {
            barrier(CLK_LOCAL_MEM_FENCE);
            for (int e = first; e < BMFR_NLM_LOCAL; e += BMFR_NLM_TILE * BMFR_NLM_TILE) {
                int ax = x0 + e % BMFR_NLM_SIDE, ay = y0 + e / BMFR_NLM_SIDE;
                int bx = ax + dx, by = ay + dy;
                float4 t = (float4)(0.0f);
                if (ax >= 0 && ax < w && ay >= 0 && ay < h && bx >= 0 && bx < w && by >= 0
                    && by < h) {
                    __local const float4* a = tile + 4 * e;
                    __global const float4* b = nlm_in + 4 * ((uint)by * width + (uint)bx);
                    float3 va = a[3].xyz, vb = b[3].xyz;
                    float3 s = va + fmin(va, vb);
                    float3 inv = 1.0f / (BMFR_NLM_EPSILON + k2 * (va + vb));
                    float d[3];
                    for (int m = 0; m < 3; ++m) {
                        float3 diff = a[m].xyz - b[m].xyz;
                        float3 q = m == 0 ? (diff * diff - s) * inv
                                          : (0.5f * (diff * diff) - s) * inv;
                        d[m] = q.x + q.y + q.z;
                    }
                    t = (float4)(d[0], d[1], d[2], 1.0f);
                }
                dist[e] = t;
            }
            barrier(CLK_LOCAL_MEM_FENCE);
            int qx = x + dx, qy = y + dy;
            if (!active || qx < 0 || qx >= w || qy < 0 || qy >= h) continue;
            uint j = (uint)qy * width + (uint)qx;
            if (nlm_in[4 * j].w != class) continue;
            // Each patch row's taps first, then the rows (bmfr_nlm_packed's order).
            float4 t = (float4)(0.0f);
            for (int ty = 0; ty < BMFR_NLM_TAPS; ++ty) {
                __local const float4* row = dist + (ly + ty) * BMFR_NLM_SIDE + lx;
                float4 sum = row[0];
                for (int tx = 1; tx < BMFR_NLM_TAPS; ++tx) sum += row[tx];
                t += sum;
            }
            float d2[3] = {t.x, t.y, t.z};
            float taps = 3.0f * t.w;
            int images = BMFR_NLM_ESTIMATING(dx, dy) ? 3 : 1;
            for (int m = 0; m < images; ++m) {
                float wt = exp(-fmax(d2[m] / taps, 0.0f));
                acc[m] += wt * nlm_in[4 * j + m].xyz;
                wsum[m] += wt;
            }
        }
    }
    if (!inside) return;
    __global const FilterVector* f = fv + i;
    float3 al = bmfr_nlm_modulation(f, class);
    if (!active) {
        bmfr_nlm_pass_through(f, odd_halves[i], spp, nlm_out + 3 * i);
        return;
    }
    // The pixel is its own neighbour (d^2 <= 0, weight 1), so every wsum >= 1.
    for (int m = 0; m < 3; ++m) nlm_out[3 * i + m] = (float4)(acc[m] / wsum[m] * al, 0.0f);
}

// Pixel i's (V, R, N, class) of n pixels: one float4, or with BMFR_RESIDUAL_PLANES (the packed
// selection, filters/bmfr_select_packed.cl) element c at plane c, c * n + i, so that 16
// adjacent pixels' V (R, N, class) are one vector load there.
inline void bmfr_store_residual(__global float4* residuals, uint i, uint n, float4 e) {
#if BMFR_RESIDUAL_PLANES
    __global float* planes = (__global float*)residuals;
    planes[i] = e.x;
    planes[n + i] = e.y;
    planes[2 * n + i] = e.z;
    planes[3 * n + i] = e.w;
#else
    residuals[i] = e;
#endif
}

// bmfr_residuals_nlm: per pixel of a class, summed over the channels, (V, R, N, class): V the
// variance of the frame's mean (as bmfr_residuals), R = (f - y)^2 the fit's residual (0 for an
// open pixel, which has no fit), and N the
// cross-half estimate of the non-local means' squared error at half the samples,
// ((nlm(o) - e)^2 - v_e + (nlm(e) - o)^2 - v_o) / 2, with v_o = (o - e)^2 n_e / n and
// v_e = (o - e)^2 n_o / n the variances of the halves' means. With BMFR_SELECT_RELATIVE each
// channel's three terms are first divided by l^2 + BMFR_RELATIVE_EPSILON, l the larger of the
// fit and the frame's non-local means (the non-local means alone for an open pixel), so that
// the window's sums weigh every pixel's relative error alike (src/filters/bmfr/nlm.rs,
// "Relative sums").
__kernel void bmfr_residuals_nlm(__global const FilterVector* fv,
                                 __global const float4* odd_halves,
                                 uint width, uint height, float spp,
                                 __global const float4* raw,
                                 __global const float4* fitted,
                                 __global const float4* nlm_out,
                                 __global float4* residuals) {
    int x = get_global_id(0), y = get_global_id(1);
    if (x >= (int)width || y >= (int)height) return;
    uint i = (uint)y * width + (uint)x;
    __global const FilterVector* f = fv + i;
    float4 odd = odd_halves[i];
    float class = raw[i].w;                  // bmfr_nlm_class_at, from bmfr_nlm_prep
    if (class == 0.0f) {
        bmfr_store_residual(residuals, i, width * height, (float4)(0.0f));
        return;
    }
    float n_odd = odd.w, n_even = spp - odd.w;
    float3 beauty = bmfr_beauty(f);
    float3 even = bmfr_even(beauty, odd, spp);
    // An open pixel's "fit" is its light: R = 0.
    float3 fit = class == BMFR_NLM_OPEN ? beauty : fitted[i].xyz;
    float3 rr, v;
    bmfr_fit_terms(beauty, fit, odd, spp, &rr, &v);
    float3 oe = odd.xyz - even;
    float3 v_odd = oe * oe * (n_even / spp);
    float3 v_even = oe * oe * (n_odd / spp);
    float3 no = nlm_out[3 * i + 1].xyz - even;
    float3 ne = nlm_out[3 * i + 2].xyz - odd.xyz;
    float3 n = 0.5f * ((no * no - v_even) + (ne * ne - v_odd));
#if BMFR_SELECT_RELATIVE
    float3 smooth = nlm_out[3 * i].xyz;
    float3 level = class == BMFR_NLM_OPEN ? smooth : fmax(fit, smooth);
    float3 weight = 1.0f / (level * level + BMFR_RELATIVE_EPSILON);
    v *= weight;
    rr *= weight;
    n *= weight;
#endif
    bmfr_store_residual(residuals, i, width * height,
                        (float4)(v.x + v.y + v.z, rr.x + rr.y + rr.z, n.x + n.y + n.z, class));
}

// bmfr_select_nlm: the window sums V, R, N over the (2 r + 1)^2 pixels around, the three
// candidates' error estimates E_y = V (the unfiltered light), E_f = (R - V) / kappa (the fit,
// trusted kappa times more than its estimate, as in bmfr_select) and E_n = N / 2 (the non-local
// means of the whole frame: N is measured at half the samples, and the variance halves with
// twice the samples), each relative to V and floored at 1e-6, and the blend of the three with
// weights 1 / E^2; the sums run over the pixels of the pixel's class, and an open pixel blends
// the light and the non-local means only (it has no fit). A window with V = 0 keeps the light
// where R > 0 and the fit where R = 0 too (only kept pixels, or one sample: no estimate).
// With BMFR_SELECT_FLOOR c > 0, R - V is summed again, each pixel's term no lower than -c times
// the window's mean V (src/filters/bmfr/nlm.rs, "The floor").
//
// With the floor the first pass also sums R - V, in the same order as the floor's pass, and
// keeps its least term. Where no term lies below the floor that pass would add the same terms
// in the same order (fmax(e, f) is e when e >= f), so its sum is the first pass's, bit for
// bit, and the pass is skipped. A NaN term makes the sum NaN and takes the pass (which floors
// it). On CPU devices bmfr_select_nlm_packed (filters/bmfr_select_packed.cl) sums the windows
// on float16 lanes and blends with the same functions: the same bytes.

// The floor of the terms R - V in a window whose V sums to sum_v over `count` pixels.
inline float bmfr_select_floor_of(float sum_v, float count) {
    return -BMFR_SELECT_FLOOR * (sum_v / count);
}

// Whether the floor's pass must run for a pixel of `class` whose window sums are `sum` over
// `count` pixels, R - V summing to excess_sum with excess_min the least term (see above).
inline bool bmfr_select_needs_floor(float class, float3 sum, float count, float excess_sum,
                                    float excess_min) {
    if (!(BMFR_SELECT_FLOOR > 0.0f) || class != BMFR_NLM_SURFACE || !(sum.x > 0.0f)) return false;
    return !(excess_min >= bmfr_select_floor_of(sum.x, count)) || isnan(excess_sum);
}

// The blend for the pixel of F `f` and class `class`, from its window's sums (V, R, N) and the
// fit's evidence `excess` (sum R - V, each term floored with the floor): the new *fitted, left
// as it is where there is no estimate. `nlm` is the pixel's non-local means of the frame.
inline void bmfr_select_nlm_blend(__global const FilterVector* f, float class, float3 sum,
                                  float excess, __global const float4* nlm,
                                  __global float4* fitted) {
    float3 beauty = bmfr_beauty(f);
    if (!(sum.x > 0.0f)) {
        // No variance: with a residual the light is noise-free and the fit is off (a light
        // whose albedo is not exactly 1, seen in a reflection), so keep the light, as
        // bmfr_select's lambda = 0 does; with none either, there is no estimate.
        if (sum.y > 0.0f) *fitted = (float4)(beauty, 0.0f);
        return;
    }
    float e_y = 1.0f;
    float e_n = fmax(0.5f * sum.z / sum.x, 1.0e-6f);
    float w_y = 1.0f / (e_y * e_y), w_n = 1.0f / (e_n * e_n);
    if (class == BMFR_NLM_OPEN) {
        *fitted = (float4)((w_y * beauty + w_n * nlm->xyz) / (w_y + w_n), 0.0f);
        return;
    }
    float e_f = fmax(excess / BMFR_SELECT_SCALE / sum.x, 1.0e-6f);
    float w_f = 1.0f / (e_f * e_f);
    float weight = w_y + w_f + w_n;
    float3 out = (w_y * beauty + w_f * fitted->xyz + w_n * nlm->xyz) / weight;
    // With the guided filter (filters/bmfr_guided.cl) the blend's weight for its fourth term.
    *fitted = (float4)(out, BMFR_GUIDED ? weight : 0.0f);
}

__kernel void bmfr_select_nlm(__global const FilterVector* fv,
                              uint width, uint height,
                              __global const float4* residuals,
                              __global const float4* nlm_out,
                              __global float4* fitted) {
    int x = get_global_id(0), y = get_global_id(1);
    if (x >= (int)width || y >= (int)height) return;
    uint i = (uint)y * width + (uint)x;
    float class = residuals[i].w;
    float3 sum = (float3)(0.0f);
    float count = 0.0f;
    float excess_sum = 0.0f, excess_min = INFINITY;
    BMFR_SELECT_WINDOW_BEGIN
        float4 e = residuals[j];
        if (e.w == class) {
            sum += e.xyz;
            count += 1.0f;
            if (BMFR_SELECT_FLOOR > 0.0f) {
                excess_sum += e.y - e.x;
                excess_min = fmin(excess_min, e.y - e.x);
            }
        }
    BMFR_SELECT_WINDOW_END
    float excess = BMFR_SELECT_FLOOR > 0.0f ? excess_sum : sum.y - sum.x;
    if (bmfr_select_needs_floor(class, sum, count, excess_sum, excess_min)) {
        float floor_ = bmfr_select_floor_of(sum.x, count);
        excess = 0.0f;
        BMFR_SELECT_WINDOW_BEGIN
            float4 e = residuals[j];
            if (e.w == class) excess += fmax(e.y - e.x, floor_);
        BMFR_SELECT_WINDOW_END
    }
    bmfr_select_nlm_blend(fv + i, class, sum, excess, nlm_out + 3 * i, fitted + i);
}
