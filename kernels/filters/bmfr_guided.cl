// The selection's fourth candidate (`guided`, src/filters/bmfr/guided.rs, its Rust reference
// with the same float operations in the same order): a guided filter (He, Sun and Tang, ECCV
// 2010) of the albedo-demodulated light on six guides, the mean shading normal and the scaled
// mean first-hit position, over (2 r + 1)^2 windows of surface pixels; the models of the
// windows covering a pixel averaged, each weighted by its count. Every window sum is a box
// sum, rows first, then columns, so the work per pixel does not grow with r^2.
//
// Planes: moment c of pixel i at [c * pixels + i] (BMFR_GUIDED_MOMENTS of them, then the
// BMFR_GUIDED_MODEL floats of each window's model times its count in the same buffers).

#define BMFR_GUIDES 6
#define BMFR_GUIDED_TARGETS 9
#define BMFR_GUIDED_PRODUCTS (BMFR_GUIDES * (BMFR_GUIDES + 1) / 2)
#define BMFR_GUIDED_T (1 + BMFR_GUIDES + BMFR_GUIDED_PRODUCTS)       // first target moment
#define BMFR_GUIDED_XT (BMFR_GUIDED_T + BMFR_GUIDED_TARGETS)          // first guide x target
#define BMFR_GUIDED_MOMENTS (BMFR_GUIDED_XT + BMFR_GUIDES * BMFR_GUIDED_TARGETS)
#define BMFR_GUIDED_B (BMFR_GUIDES * BMFR_GUIDED_TARGETS)            // first offset of a model
#define BMFR_GUIDED_MODEL (BMFR_GUIDED_B + BMFR_GUIDED_TARGETS + 1)

inline void bmfr_guided_guides(__global const FilterVector* f, __global const float4* pos,
                               float* x) {
    float4 p = *pos;
    x[0] = f->normal[0];
    x[1] = f->normal[1];
    x[2] = f->normal[2];
    x[3] = p.x * BMFR_GUIDED_SCALE;
    x[4] = p.y * BMFR_GUIDED_SCALE;
    x[5] = p.z * BMFR_GUIDED_SCALE;
}

// The pixel's terms of the window sums, added to acc (guided.rs `moments`).
inline void bmfr_guided_add_moments(__global const FilterVector* f, __global const float4* pos,
                                    float4 odd, float spp, float* acc) {
    float x[BMFR_GUIDES];
    bmfr_guided_guides(f, pos, x);
    float3 b = bmfr_beauty(f), e = bmfr_even(b, odd, spp), al = bmfr_albedo(f);
    float3 t0 = b / al, t1 = odd.xyz / al, t2 = e / al;
    float t[BMFR_GUIDED_TARGETS] = {t0.x, t0.y, t0.z, t1.x, t1.y, t1.z, t2.x, t2.y, t2.z};
    acc[0] += 1.0f;
    for (int d = 0; d < BMFR_GUIDES; ++d) acc[1 + d] += x[d];
    int n = 1 + BMFR_GUIDES;
    for (int a = 0; a < BMFR_GUIDES; ++a)
        for (int c = a; c < BMFR_GUIDES; ++c) acc[n++] += x[a] * x[c];
    for (int k = 0; k < BMFR_GUIDED_TARGETS; ++k) acc[n++] += t[k];
    for (int d = 0; d < BMFR_GUIDES; ++d)
        for (int k = 0; k < BMFR_GUIDED_TARGETS; ++k) acc[n++] += x[d] * t[k];
}

// Row sums of the surface pixels' moments: x - r .. x + r inside the image, left to right.
// `raw`'s w is the pixel's class (bmfr_nlm_prep).
__kernel void bmfr_guided_rows(__global const FilterVector* fv, __global const float4* positions,
                               __global const float4* odd_halves, uint width, uint height,
                               float spp, __global const float4* raw, __global float* planes) {
    int x = get_global_id(0), y = get_global_id(1);
    if (x >= (int)width || y >= (int)height) return;
    size_t pixels = (size_t)width * height, i = (size_t)y * width + x;
    float acc[BMFR_GUIDED_MOMENTS];
    for (int c = 0; c < BMFR_GUIDED_MOMENTS; ++c) acc[c] = 0.0f;
    int x0 = max(x - BMFR_GUIDED_RADIUS, 0), x1 = min(x + BMFR_GUIDED_RADIUS, (int)width - 1);
    for (int xx = x0; xx <= x1; ++xx) {
        size_t j = (size_t)y * width + xx;
        if (raw[j].w == BMFR_NLM_SURFACE)
            bmfr_guided_add_moments(fv + j, positions + j, odd_halves[j], spp, acc);
    }
    for (int c = 0; c < BMFR_GUIDED_MOMENTS; ++c) planes[c * pixels + i] = acc[c];
}

// Column sums of `n` planes: the rows' sums of y - r .. y + r inside the image, top to bottom.
inline void bmfr_guided_columns(__global const float* planes, int n, int x, int y, uint width,
                                uint height, float* acc) {
    size_t pixels = (size_t)width * height;
    for (int c = 0; c < n; ++c) acc[c] = 0.0f;
    int y0 = max(y - BMFR_GUIDED_RADIUS, 0), y1 = min(y + BMFR_GUIDED_RADIUS, (int)height - 1);
    for (int yy = y0; yy <= y1; ++yy) {
        size_t j = (size_t)yy * width + x;
        for (int c = 0; c < n; ++c) acc[c] += planes[c * pixels + j];
    }
}

// Each window's model: the guides' covariance plus the ridge, its Cholesky factor, the
// slopes for the nine targets and their offsets, all times the window's count (guided.rs
// `solve`); a window without surface pixels has none (zeros).
__kernel void bmfr_guided_solve(__global const FilterVector* fv, uint width, uint height,
                                __global const float* moments, __global float* models) {
    int x = get_global_id(0), y = get_global_id(1);
    if (x >= (int)width || y >= (int)height) return;
    size_t pixels = (size_t)width * height, i = (size_t)y * width + x;
    float s[BMFR_GUIDED_MOMENTS];
    bmfr_guided_columns(moments, BMFR_GUIDED_MOMENTS, x, y, width, height, s);
    float m = s[0];
    if (!(m >= 1.0f)) {
        for (int c = 0; c < BMFR_GUIDED_MODEL; ++c) models[c * pixels + i] = 0.0f;
        return;
    }
    float xm[BMFR_GUIDES], tm[BMFR_GUIDED_TARGETS];
    for (int d = 0; d < BMFR_GUIDES; ++d) xm[d] = s[1 + d] / m;
    for (int k = 0; k < BMFR_GUIDED_TARGETS; ++k) tm[k] = s[BMFR_GUIDED_T + k] / m;
    float c[BMFR_GUIDES][BMFR_GUIDES];
    int n = 1 + BMFR_GUIDES;
    for (int a = 0; a < BMFR_GUIDES; ++a)
        for (int b = a; b < BMFR_GUIDES; ++b) {
            float v = s[n++] / m - xm[a] * xm[b];
            c[a][b] = a == b ? v + BMFR_GUIDED_RIDGE : v;
            c[b][a] = c[a][b];
        }
    float l[BMFR_GUIDES][BMFR_GUIDES];
    for (int r = 0; r < BMFR_GUIDES; ++r)
        for (int j = 0; j <= r; ++j) {
            float v = c[r][j];
            for (int k = 0; k < j; ++k) v -= l[r][k] * l[j][k];
            l[r][j] = r == j ? sqrt(fmax(v, BMFR_GUIDED_RIDGE)) : v / l[j][j];
        }
    for (int k = 0; k < BMFR_GUIDED_TARGETS; ++k) {
        float z[BMFR_GUIDES], a[BMFR_GUIDES];
        for (int r = 0; r < BMFR_GUIDES; ++r) {
            float v = s[BMFR_GUIDED_XT + r * BMFR_GUIDED_TARGETS + k] / m - xm[r] * tm[k];
            for (int j = 0; j < r; ++j) v -= l[r][j] * z[j];
            z[r] = v / l[r][r];
        }
        for (int r = BMFR_GUIDES - 1; r >= 0; --r) {
            float v = z[r];
            for (int j = r + 1; j < BMFR_GUIDES; ++j) v -= l[j][r] * a[j];
            a[r] = v / l[r][r];
        }
        float b = tm[k];
        for (int d = 0; d < BMFR_GUIDES; ++d) {
            b -= a[d] * xm[d];
            models[(d * BMFR_GUIDED_TARGETS + k) * pixels + i] = m * a[d];
        }
        models[(BMFR_GUIDED_B + k) * pixels + i] = m * b;
    }
    models[(BMFR_GUIDED_MODEL - 1) * pixels + i] = m;
}

// Row sums of the windows' models (all windows: one without surface pixels adds zeros).
__kernel void bmfr_guided_average_rows(__global const FilterVector* fv, uint width, uint height,
                                       __global const float* models, __global float* rows) {
    int x = get_global_id(0), y = get_global_id(1);
    if (x >= (int)width || y >= (int)height) return;
    size_t pixels = (size_t)width * height, i = (size_t)y * width + x;
    int x0 = max(x - BMFR_GUIDED_RADIUS, 0), x1 = min(x + BMFR_GUIDED_RADIUS, (int)width - 1);
    for (int c = 0; c < BMFR_GUIDED_MODEL; ++c) {
        float acc = 0.0f;
        for (int xx = x0; xx <= x1; ++xx) acc += models[c * pixels + (size_t)y * width + xx];
        rows[c * pixels + i] = acc;
    }
}

// A surface pixel's output from its averaged model's value at its guides per target (g,
// clamped at 0, demodulated): the frame's light modulated back in xyz and the cross-half
// error term G in w (guided.rs `guided`). `fitted` is the fit's, `smooth` the frame's
// non-local means' (the relative sums' level).
inline float4 bmfr_guided_output(__global const FilterVector* f, float4 odd, float spp,
                                 float* g, float4 fitted, float4 smooth) {
    float3 al = bmfr_albedo(f);
    float alc[3] = {al.x, al.y, al.z};
    for (int k = 0; k < BMFR_GUIDED_TARGETS; ++k) g[k] *= alc[k % 3];
    float3 b = bmfr_beauty(f), e = bmfr_even(b, odd, spp);
    float n_odd = odd.w, n_even = spp - odd.w;
    float3 oe = odd.xyz - e;
    float3 v_odd = oe * oe * (n_even / spp), v_even = oe * oe * (n_odd / spp);
    float3 go = (float3)(g[3], g[4], g[5]) - e, ge = (float3)(g[6], g[7], g[8]) - odd.xyz;
    float3 t = 0.5f * ((go * go - v_even) + (ge * ge - v_odd));
#if BMFR_SELECT_RELATIVE
    float3 level = fmax(fitted.xyz, smooth.xyz);
    t *= 1.0f / (level * level + BMFR_RELATIVE_EPSILON);
#endif
    return (float4)(g[0], g[1], g[2], t.x + t.y + t.z);
}

// Per surface pixel: the averaged model evaluated at its guides (bmfr_guided_output); zeros
// elsewhere. `fitted` holds the fit, `nlm_out` the frame's non-local means.
__kernel void bmfr_guided_eval(__global const FilterVector* fv, __global const float4* positions,
                               __global const float4* odd_halves, uint width, uint height,
                               float spp, __global const float4* raw,
                               __global const float* rows, __global const float4* fitted,
                               __global const float4* nlm_out, __global float4* guided) {
    int x = get_global_id(0), y = get_global_id(1);
    if (x >= (int)width || y >= (int)height) return;
    size_t i = (size_t)y * width + x;
    if (raw[i].w != BMFR_NLM_SURFACE) {
        guided[i] = (float4)(0.0f);
        return;
    }
    __global const FilterVector* f = fv + i;
    float s[BMFR_GUIDED_MODEL];
    bmfr_guided_columns(rows, BMFR_GUIDED_MODEL, x, y, width, height, s);
    float xg[BMFR_GUIDES];
    bmfr_guided_guides(f, positions + i, xg);
    float count = s[BMFR_GUIDED_MODEL - 1];
    float g[BMFR_GUIDED_TARGETS];
    for (int k = 0; k < BMFR_GUIDED_TARGETS; ++k) {
        float v = s[BMFR_GUIDED_B + k] / count;
        for (int d = 0; d < BMFR_GUIDES; ++d) v += s[d * BMFR_GUIDED_TARGETS + k] / count * xg[d];
        g[k] = fmax(v, 0.0f);
    }
    guided[i] = bmfr_guided_output(f, odd_halves[i], spp, g, fitted[i], nlm_out[3 * i]);
}

// After the selection: where it blended the light, the fit and the non-local means with total
// weight W (kept in the output's w), the guided filter joins the blend with weight 1 / E_g^2,
// E_g = G / 2 over the window's V, both summed over the window's surface pixels (guided.rs
// `blend`); the output's w is 0 again. `class` is the pixel's, `v` and `gs` the window's sums.
// The packed selection (filters/bmfr_select_packed.cl) calls it with the sums it already has.
inline void bmfr_guided_join(float class, float v, float gs, float4 guided,
                             __global float4* fitted) {
    float4 selected = *fitted;
    float weight = selected.w;
    if (class != BMFR_NLM_SURFACE || !(weight > 0.0f)) {
        *fitted = (float4)(selected.xyz, 0.0f);
        return;
    }
    float e_g = fmax(0.5f * gs / v, 1.0e-6f);
    float w_g = 1.0f / (e_g * e_g);
    float3 out = (weight * selected.xyz + w_g * guided.xyz) / (weight + w_g);
    *fitted = (float4)(out, 0.0f);
}

// bmfr_guided_join after the work-group selection (bmfr_select_nlm), with the window's sums.
__kernel void bmfr_guided_blend(__global const FilterVector* fv, uint width, uint height,
                                __global const float4* residuals, __global const float4* guided,
                                __global float4* fitted) {
    int x = get_global_id(0), y = get_global_id(1);
    if (x >= (int)width || y >= (int)height) return;
    size_t i = (size_t)y * width + x;
    float class = residuals[i].w;
    float v = 0.0f, gs = 0.0f;
    if (class == BMFR_NLM_SURFACE) {
        for (int yy = y - BMFR_SELECT_RADIUS; yy <= y + BMFR_SELECT_RADIUS; ++yy) {
            if (yy < 0 || yy >= (int)height) continue;
            for (int xx = x - BMFR_SELECT_RADIUS; xx <= x + BMFR_SELECT_RADIUS; ++xx) {
                if (xx < 0 || xx >= (int)width) continue;
                size_t j = (size_t)yy * width + xx;
                if (residuals[j].w == BMFR_NLM_SURFACE) {
                    v += residuals[j].x;
                    gs += guided[j].w;
                }
            }
        }
    }
    bmfr_guided_join(class, v, gs, guided[i], fitted + i);
}
