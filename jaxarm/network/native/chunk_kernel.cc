// Native CPU kernel for one chunk of network steps (jaxarm.network.native; the XLA path is
// jaxarm.network.network.Network._chunk). Units: ms and mV, as in the Python network.
//
// Same model, same order of operations per step as the XLA path:
//   1. the generators' input (the paper's P -> ES) of the whole chunk written into the ring at the chunk start
//      (deliver_p_window); "P" below stands for every generator cell (ids n_all - n_p .. n_all - 1);
//   2. per step m: read and clear ring slot m % n_slots; Poisson noise counts from the integer hash
//      (bit-identical to noise.noise_counts), limited by each lane's event budget (noise.draw_events); INTF6 cell
//      update (cell.cell_step); P trains (proprio.p_step);
//      last / previous spike times and spike counts; spikes of the step delivered into the ring at
//      (m + delay) % n_slots and plastic inputs tagged.
// The XLA path delivers after blocks of L <= the shortest delay and refractory period; delivering each spike at
// its own step is the same (its arrival slot is not read before m + delay; a cell fires at most once per block,
// so "the presynaptic spike at or before t_post" is the same spike). Spike lists have no capacity here: nothing
// is ever lost and no extra passes exist. Floating-point results differ from XLA's in the last bits (exp/log
// implementations: fastmath below, summation order); the noise counts are exact.
//
// Batching: every input carries the batch dimensions of vmap's "expand_dims" method in front of its per-network
// shape (size 1 where not batched); the kernel broadcasts them, so shared wiring is read in place, never copied.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <thread>
#include <vector>
#ifdef __AVX__
#include <immintrin.h>
#endif

#include "xla/ffi/api/ffi.h"

namespace ffi = xla::ffi;

// The per-block lane functions inlined into their loops: called, every block reloaded the arrays' pointers and
// the block lists' counters through memory (a chain from one block to the next)
#define ALWAYS_INLINE inline __attribute__((always_inline))

// Phase timers for benchmarks/profile.py: built only with -DJAXARM_PROFILE (a library of its own, see
// jaxarm.network.native.enable_profiling); the production build compiles every PROF_ macro to nothing. Not
// thread-safe: profile with one kernel thread.
#ifdef JAXARM_PROFILE
#include <chrono>
namespace prof {
enum Phase { kCopyIn, kPWindow, kNoise, kCells, kSpikeBookkeeping, kDelivery, kTags, kNumPhases };
int64_t ns[kNumPhases];
int64_t spikes, synapse_events, tag_checks, steps;
// cell blocks updated, and of them those with input at AMPA, NMDA, GABA-prox, GABA-dist (the jumps computed)
constexpr int kReceptors = 4;   // the rows of the kernel's input (enum Receptor)
int64_t cell_blocks, blocks_with_input[kReceptors];
inline int64_t now() { return std::chrono::steady_clock::now().time_since_epoch().count(); }
}  // namespace prof
#define PROF_START int64_t prof_t = prof::now();
#define PROF_MARK(phase)                  \
  {                                       \
    const int64_t prof_n = prof::now();   \
    prof::ns[prof::phase] += prof_n - prof_t; \
    prof_t = prof_n;                      \
  }
#define PROF_COUNT(counter, k) prof::counter += (k);
extern "C" void JaxarmProfileRead(int64_t* out) {   // ns per phase, then the nine event counters
  for (int k = 0; k < prof::kNumPhases; ++k) out[k] = prof::ns[k];
  out[prof::kNumPhases] = prof::spikes;
  out[prof::kNumPhases + 1] = prof::synapse_events;
  out[prof::kNumPhases + 2] = prof::tag_checks;
  out[prof::kNumPhases + 3] = prof::steps;
  out[prof::kNumPhases + 4] = prof::cell_blocks;
  for (int r = 0; r < prof::kReceptors; ++r) out[prof::kNumPhases + 5 + r] = prof::blocks_with_input[r];
}
extern "C" void JaxarmProfileReset() {
  for (int k = 0; k < prof::kNumPhases; ++k) prof::ns[k] = 0;
  prof::spikes = prof::synapse_events = prof::tag_checks = prof::steps = 0;
  prof::cell_blocks = 0;
  for (int64_t& b : prof::blocks_with_input) b = 0;
}
#else
#define PROF_START
#define PROF_MARK(phase)
#define PROF_COUNT(counter, k)
#endif

namespace {

// The physics (reversal potentials, Mg block, clamp, jump cap) and the delay packing come from the network spec as
// attributes (Attrs), so no constant of the model is written both here and in Python.
constexpr int32_t kSinceMax = 1 << 30;
constexpr int32_t kNever = 1 << 30;
constexpr uint32_t kGolden = 0x9E3779B9u;
constexpr uint32_t kOrderSalt = 0x5BD1E995u;   // noise.ORDER_SALT

// Inputs, in order (per-network shapes; see jaxarm/network/native/__init__.py).
enum In {
  kStep, kAmpa, kNmda, kGabaProx, kGabaDist, kAhp, kExcess, kSince, kPNext, kPInterval, kStepSeed, kLaneKey,
  kThresholds, kRing, kWgain, kPdope, kLast, kPrev, kCount, kWindow, kPPre, kPDelay, kPTarget, kPWeight, kPNmda,
  kCellF, kNRef, kNoiseW, kCellGroup, kCellRow, kEventsLeft, kPSyn, kGroupTables  // then 6 tables per group
};
constexpr int kTablesPerGroup = 6;  // out_syn, out_packed, out_weight, out_nmda, in_plastic, in_plastic_pre
// Outputs, in order.
enum Out { oStep, oAmpa, oNmda, oGabaProx, oGabaDist, oAhp, oExcess, oSince, oPNext, oRing, oPdope, oLast, oPrev,
           oCount, oEventsLeft, oSpikes, kNumOut };
// Per-network rank of every input (the rest of an input's dimensions are batch dimensions).
constexpr int kBaseRankFixed[] = {0, 1, 1, 1, 1, 1, 1, 1, 1, 1, 0, 2, 3, 1, 1, 1, 1, 1, 1, 0, 1, 1, 1, 1, 1,
                                  2, 1, 2, 1, 1, 2, 1};
constexpr int kBaseRankOut[] = {0, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 2, 2};

inline uint32_t hash32(uint32_t x) {
  x ^= x >> 16;
  x *= 0x7FEB352Du;
  x ^= x >> 15;
  x *= 0x846CA68Bu;
  return x ^ (x >> 16);
}

// Lanes for the cells' update: one cell (float, int32_t, bool) or a block of kLanes cells (vf, vi, vi masks of
// all-ones / zero) with the same operations, so one function body serves the vector blocks and the scalar tail.
// GCC/Clang vector extensions: portable (AVX2 here, NEON on ARM), no intrinsics.
namespace simd {
constexpr int kLanes = 8;
typedef float vf __attribute__((vector_size(4 * kLanes)));
typedef int32_t vi __attribute__((vector_size(4 * kLanes)));
typedef int8_t vb __attribute__((vector_size(kLanes)));
typedef uint32_t vu __attribute__((vector_size(4 * kLanes)));
template <class T> struct IntOf { typedef int32_t type; };
template <> struct IntOf<vf> { typedef vi type; };
template <class T> inline T splat(float x) { return T{} + x; }
template <> inline float splat<float>(float x) { return x; }
template <class T> inline T splat_int(int32_t x) { return T{} + x; }
template <> inline int32_t splat_int<int32_t>(int32_t x) { return x; }
// std::min / std::max's own comparisons, so NaN-free inputs give the scalar's results in every lane
inline float min(float a, float b) { return std::min(a, b); }
inline float max(float a, float b) { return std::max(a, b); }
inline int32_t min(int32_t a, int32_t b) { return std::min(a, b); }
inline vf min(vf a, vf b) { return b < a ? b : a; }
inline vf max(vf a, vf b) { return a < b ? b : a; }
inline vi min(vi a, vi b) { return b < a ? b : a; }
// a float's bits and back, an integer's value as a float: lane by lane
inline int32_t to_bits(float x) { int32_t b; std::memcpy(&b, &x, 4); return b; }
inline vi to_bits(vf x) { return (vi)x; }
template <class T> inline T from_bits(int32_t b) { float x; std::memcpy(&x, &b, 4); return x; }
template <class T> inline T from_bits(vi b) { return (vf)b; }
template <class T> inline T to_float(int32_t x) { return float(x); }
template <class T> inline T to_float(vi x) { return __builtin_convertvector(x, vf); }
// floor of |x| < 2^31: truncate, then step down where truncation rounded up (negative non-integers); = std::floor
inline float floor(float x) { return std::floor(x); }
inline vf floor(vf x) {
#ifdef __AVX__
  return (vf)_mm256_floor_ps((__m256)x);
#else
  const vf t = __builtin_convertvector(__builtin_convertvector(x, vi), vf);
  return t > x ? t - 1.0f : t;
#endif
}
// 2^k for integral k in the float exponent range
inline float pow2(float k) {
  const int32_t b = (int32_t(k) + 127) << 23;
  float f;
  std::memcpy(&f, &b, 4);
  return f;
}
inline vf pow2(vf k) { return (vf)((__builtin_convertvector(k, vi) + 127) << 23); }
inline bool any(bool m) { return m; }
inline bool any(vi m) {
#ifdef __AVX__
  return !_mm256_testz_si256((__m256i)m, (__m256i)m);
#else
  uint64_t w[kLanes / 2];
  std::memcpy(w, &m, sizeof m);
  uint64_t o = 0;
  for (int k = 0; k < kLanes / 2; ++k) o |= w[k];
  return o != 0;
#endif
}
template <class T> inline T load(const float* p) { T x; std::memcpy(&x, p, sizeof x); return x; }
template <class T> inline T load(const int32_t* p) { T x; std::memcpy(&x, p, sizeof x); return x; }
inline void store(float* p, float x) { *p = x; }
inline void store(float* p, vf x) { std::memcpy(p, &x, sizeof x); }
inline void store(int32_t* p, int32_t x) { *p = x; }
inline void store(int32_t* p, vi x) { std::memcpy(p, &x, sizeof x); }
inline void store_flag(uint8_t* p, bool m) { *p = m; }
inline void store_flag(uint8_t* p, vi m) {
#ifdef __AVX2__   // the lanes' masks narrowed by two saturating packs (the generic conversion extracts lane by lane)
  const __m128i w = _mm_packs_epi32(_mm256_castsi256_si128((__m256i)m), _mm256_extracti128_si256((__m256i)m, 1));
  _mm_storel_epi64(reinterpret_cast<__m128i*>(p), _mm_and_si128(_mm_packs_epi16(w, w), _mm_set1_epi8(1)));
#else
  const vb b = __builtin_convertvector(m, vb) & 1;
  std::memcpy(p, &b, sizeof b);
#endif
}
}  // namespace simd

// Branch-free float exp, expm1 and log1p, so the loops that call them vectorise (glibc's scalar calls were a fifth
// of the kernel's time). Cody-Waite reduction and the Cephes minimax polynomials for exp and log; expm1 by the same
// reduction and the Taylor series of expm1 (to r^9) on the reduced argument; log1p as log(u) + (x - (u - 1)) / u with u = 1 + x
// rounded (the first-order correction of that rounding), by its series for |x| < 1e-3.
// Errors against the exact functions, measured in tests/test_native_math.py over their whole float ranges: at most
// 0.97 ulp (exp), 1.5 ulp (expm1, near x = ln2 / 2) and 1.1 ulp (log1p); mean 0.2-0.3 ulp.
namespace fastmath {
// exp, expm1, log and log1p are templates over a lane type: float, or simd::vf (eight floats in GCC/Clang vector
// extensions: the cells' update and delivery's event loads in blocks). Every lane takes exactly the scalar's
// operations, selects in place of branches, so both give the same bits (tests/test_native_math.py).
template <class T>
inline T exp(T x) {
  x = simd::min(simd::max(x, simd::splat<T>(-87.3f)), simd::splat<T>(88.7f));
  const T k = simd::floor(x * 1.44269504088896341f + 0.5f);
  const T r = (x - k * 0.693359375f) - k * -2.12194440e-4f;
  const T z = r * r;
  const T p = (((((1.9875691500e-4f * r + 1.3981999507e-3f) * r + 8.3334519073e-3f) * r + 4.1665795894e-2f) * r +
                1.6666665459e-1f) * r + 5.0000001201e-1f) * z + r + 1.0f;
  return p * simd::pow2(k);
}
template <class T>
inline T expm1(T x) {
  // expm1(x) = 2^k (expm1(r) + 1) - 1, r = x - k ln2 in [-ln2/2, ln2/2]: one polynomial for every x (no exp and
  // no select between two computations, which a vectorised loop would both pay for)
  x = simd::min(simd::max(x, simd::splat<T>(-87.3f)), simd::splat<T>(88.7f));
  const T k = simd::floor(x * 1.44269504088896341f + 0.5f);
  const T r = (x - k * 0.693359375f) - k * -2.12194440e-4f;
  const T t = r * (1.0f / 2 + r * (1.0f / 6 + r * (1.0f / 24 + r * (1.0f / 120 + r * (1.0f / 720 + r * (
      1.0f / 5040 + r * (1.0f / 40320 + r * (1.0f / 362880))))))));
  const T p = r + r * t;                                  // expm1(r)
  const T scale = simd::pow2(k);
  return k == 0.0f ? p : scale * p + (scale - 1.0f);
}
template <class T>
ALWAYS_INLINE T log(T u) {   // u > 0, finite
  typedef typename simd::IntOf<T>::type I;
  const I b = simd::to_bits(u);
  I e = ((b >> 23) & 0xff) - 127;
  T m = simd::from_bits<T>((b & 0x007fffff) | 0x3f800000);   // [1, 2)
  const auto high = m > 1.41421356f;
  m = high ? 0.5f * m : m;
  e = high ? e + 1 : e;
  const T f = m - 1.0f;
  const T z = f * f;
  T y = ((((((((7.0376836292e-2f * f - 1.1514610310e-1f) * f + 1.1676998740e-1f) * f - 1.2420140846e-1f) * f +
             1.4249322787e-1f) * f - 1.6668057665e-1f) * f + 2.0000714765e-1f) * f - 2.4999993993e-1f) * f +
         3.3333331174e-1f) * f * z;
  const T ef = simd::to_float<T>(e);
  y += ef * -2.12194440e-4f;
  y -= 0.5f * z;
  return (f + y) + ef * 0.693359375f;
}
template <class T>
ALWAYS_INLINE T log1p(T x) {   // x > -1
  const T u = 1.0f + x;
  const T d = u - 1.0f;
  const T series = x - x * x * (0.5f - x * (1.0f / 3 - x * 0.25f));   // |x| < 1e-3: error below x^5 / 5
  const T general = log(u) + (x - d) / u;
  return (x < 1e-3f) & (x > -1e-3f) ? series : general;
}
}  // namespace fastmath

template <class T>
ALWAYS_INLINE T event_load(T w, float e_rev, float max_jump_fraction) {
  return -e_rev * fastmath::log1p(-simd::min(w / e_rev, simd::splat<T>(max_jump_fraction)));
}

struct View {  // one input or output: base pointer, per-network element count, element size, batch strides
  char* data;
  int64_t per_network;
  int64_t elem;
  std::vector<int64_t> batch_dims;
};

struct Attrs {
  int64_t n_steps, n_slots, n_groups, sequential, on_event, per_event, random_order, exc[8];
  float dt_ms;
  // NetworkSpec.physics, mV and 1/mV
  float e_ampa, e_nmda, e_gaba, mg, mg0, mg_slope, vm_min, vm_max, max_jump_fraction;
  int64_t delay_bits;
  bool batched;   // more than one network in this call
};

template <typename T>
inline T* at(const View& v, int64_t offset) {
  return reinterpret_cast<T*>(v.data) + offset * v.per_network;
}

// Batch offset of input v for the network with multi-index idx (broadcast where v has size 1).
inline int64_t batch_offset(const View& v, const std::vector<int64_t>& idx) {
  int64_t off = 0;
  for (size_t d = 0; d < idx.size(); ++d) off = off * v.batch_dims[d] + (v.batch_dims[d] == 1 ? 0 : idx[d]);
  return off;
}


// Noise counts N = #{k < kmax : u >= T_k} of every lane, spent against the limited lanes' budgets and added as
// N x weight to this step's input, in two passes per receptor (same counts as every lane against every threshold):
// (1) every lane's hash u and whether u >= T_0, with the list of the blocks of simd::kLanes lanes where some lane
// has an event; (2) in the listed blocks only, the count against the other thresholds, the budget and the input.
// A lane has an event in at most 5 % of the 0.25 ms steps (the paper's rates; thresholds increase, so a lane below
// T_0 counts 0), so the second pass reads the other kmax - 1 thresholds (3 at the default noise_max_rate_hz) for
// a third of the blocks or fewer. Adding nothing to a lane without an event leaves its input
// as it was (a zero input is tested as zero, whatever its sign, and the slot is cleared after the step).
// Each limited lane emits at most its remaining budget (a NetStim's `number`); lanes holding kUnlimitedEvents or
// more are unlimited and never spend (noise.UNLIMITED_EVENTS).
constexpr int32_t kUnlimitedEvents = 1 << 30;

bool any_limited(int64_t lanes, const int32_t* __restrict__ left) {
  int32_t lo = kUnlimitedEvents;
  for (int64_t l = 0; l < lanes; ++l) lo = std::min(lo, left[l]);
  return lo < kUnlimitedEvents;
}

inline simd::vu hash32(simd::vu x) {
  x ^= x >> 16;
  x *= 0x7FEB352Du;
  x ^= x >> 15;
  x *= 0x846CA68Bu;
  return x ^ (x >> 16);
}

// N = #{k < kmax : u >= T_k} of lane l; KMax > 0: kmax known at compile time (the comparisons unrolled)
template <int KMax>
inline int32_t count_events(uint32_t u, int64_t l, int64_t lanes, const uint32_t* __restrict__ thr, int64_t kmax) {
  int32_t c = 0;
  if constexpr (KMax > 0) {
#pragma GCC unroll 16
    for (int k = 0; k < KMax; ++k) c += (u >= thr[k * lanes + l]) ? 1 : 0;
  } else {
    for (int64_t k = 0; k < kmax; ++k) c += (u >= thr[k * lanes + l]) ? 1 : 0;
  }
  return c;
}

// Lane l's events from its hash u: the count, spent against a limited lane's budget, added to its input
template <int KMax>
inline void lane_noise(uint32_t u, int64_t l, int64_t lanes, int64_t kmax, const uint32_t* __restrict__ thr,
                       const float* __restrict__ w, int32_t* __restrict__ left, bool limited, float* __restrict__ in) {
  int32_t c = count_events<KMax>(u, l, lanes, thr, kmax);
  if (limited) {
    const bool lim = left[l] < kUnlimitedEvents;
    c = lim ? std::min(c, left[l]) : c;
    left[l] -= lim ? c : 0;
  }
  *in += float(c) * w[l];
}

// receptor lanes [0, n) of a lane table whose receptor r starts at r0 (key, thresholds) into input row inr
template <int KMax>
void noise_receptor(int64_t n, int64_t lanes, int64_t kmax, int64_t r0, uint32_t s, const uint32_t* __restrict__ lane_key,
                    const uint32_t* __restrict__ thr, const float* __restrict__ w, int32_t* __restrict__ left,
                    bool limited, float* __restrict__ inr, uint32_t* __restrict__ ub, int32_t* __restrict__ blocks) {
  const int64_t full = n - n % simd::kLanes;
  int32_t n_listed = 0;
  for (int64_t l = 0; l < full; l += simd::kLanes) {
    simd::vu u;
    std::memcpy(&u, lane_key + r0 + l, sizeof u);
    u = hash32(u ^ s);
    simd::vu t0;
    std::memcpy(&t0, thr + r0 + l, sizeof t0);
    std::memcpy(ub + l, &u, sizeof u);
    blocks[n_listed] = int32_t(l);
    n_listed += simd::any((simd::vi)(u >= t0));
  }
  for (int32_t b = 0; b < n_listed; ++b)
    for (int64_t l = blocks[b]; l < blocks[b] + simd::kLanes; ++l)   // vectorised: a fixed trip count
      lane_noise<KMax>(ub[l], r0 + l, lanes, kmax, thr, w, left, limited, inr + l);
  for (int64_t l = full; l < n; ++l)
    lane_noise<KMax>(hash32(lane_key[r0 + l] ^ s), r0 + l, lanes, kmax, thr, w, left, limited, inr + l);
}

// The three receptors' noise (AMPA-distal, GABA-prox, GABA-dist lanes: rows 0, 2, 3 of this step's input inb)
template <int KMax>
void add_noise_fixed(int64_t n, int64_t kmax, uint32_t s, const uint32_t* lane_key, const uint32_t* thr,
                     const float* w, int32_t* left, bool limited, float* inb, uint32_t* ub, int32_t* blocks) {
  for (int64_t r = 0; r < 3; ++r)
    noise_receptor<KMax>(n, 3 * n, kmax, r * n, s, lane_key, thr, w, left, limited, inb + (r == 0 ? 0 : r + 1) * n,
                         ub, blocks);
}

void add_noise(int64_t n, int64_t kmax, uint32_t s, const uint32_t* lane_key, const uint32_t* thr, const float* w,
               int32_t* left, bool limited, float* inb, uint32_t* ub, int32_t* blocks) {
  switch (kmax) {
    case 1: return add_noise_fixed<1>(n, kmax, s, lane_key, thr, w, left, limited, inb, ub, blocks);
    case 2: return add_noise_fixed<2>(n, kmax, s, lane_key, thr, w, left, limited, inb, ub, blocks);
    case 3: return add_noise_fixed<3>(n, kmax, s, lane_key, thr, w, left, limited, inb, ub, blocks);
    case 4: return add_noise_fixed<4>(n, kmax, s, lane_key, thr, w, left, limited, inb, ub, blocks);
    case 5: return add_noise_fixed<5>(n, kmax, s, lane_key, thr, w, left, limited, inb, ub, blocks);
    case 6: return add_noise_fixed<6>(n, kmax, s, lane_key, thr, w, left, limited, inb, ub, blocks);
    case 7: return add_noise_fixed<7>(n, kmax, s, lane_key, thr, w, left, limited, inb, ub, blocks);
    case 8: return add_noise_fixed<8>(n, kmax, s, lane_key, thr, w, left, limited, inb, ub, blocks);
    default: return add_noise_fixed<0>(n, kmax, s, lane_key, thr, w, left, limited, inb, ub, blocks);
  }
}

struct CellConstantsView {   // per-cell constants (native_cell_floats) and the physics, for the cells' passes
  const float *rmp, *vth, *vblock, *ahpwt, *post_excess, *d_ampa, *d_nmda, *d_gprox, *d_gdist, *d_ahp, *d_rr,
      *d_rr_first;
  const int32_t* n_ref;
  float e_ampa, e_nmda, e_gaba, neg_inv_ampa, inv_gaba, inv_ampa, inv_nmda, neg_mg_slope, mg_ratio, vm_min, vm_max;
};

// One clock step of every cell (jaxarm.network.cell.cell_step): decay of every component, refractory bookkeeping,
// V (the deviation every driving force of this step uses), the jumps of this step's input in[4 n] (AMPA, NMDA,
// GABA-prox, GABA-dist: loads with Seq, weights without), the threshold test into spiked[n] and a spike's own
// effects (AHP jump, threshold excess, refractory count).
// The threshold test of step t and the decay of step t + 1 go in one pass over the cells (the spike's effects
// between them, as selects), which loads and stores the state and the constants once for both. Nothing in between
// reads or writes the cells (delivery, tags and the next step's noise touch the ring and the spike times only), so
// the arithmetic, and the bits, are those of the one-cell form in its order.
// A receptor's jump needs transcendental functions, but only where that receptor has input this step, and 3-8 % of
// the cells do (in the paper's network): once the input of step t is complete, the cells with input are listed per
// receptor and their jumps computed eight listed cells at a time (jumps, below). The last n % kLanes cells take the
// same stages one cell at a time.
// PerEvent: NetworkConfig.crossing = "per_event"; OnEvent: threshold_test = "on_event"; Order:
// same_step_inhibition = "random_order" (a cell whose excitation came first and crossed fires: fires_first).
struct CellArrays {  // the cells' state (updated in place), this step's input, and the per-step scratch
  float *ampa, *nmda, *gprox, *gdist, *ahp, *excess;
  int32_t* since;
  const float* in;   // [4 n]: AMPA, NMDA, GABA-prox, GABA-dist
  float* v;          // [n] scratch: V of this step
  int32_t* listed;   // [n + kLanes] scratch: the cells with input at one receptor
  uint8_t* spiked;   // [n]
  int64_t n;
  int32_t* fires_first;      // [n] (Order): set by this step's GABA jumps, read and cleared by its threshold test
  const uint32_t* lane_key;  // the AMPA lanes' keys (Order: the coin excitation_first)
  uint32_t order_s;          // hash32(m * phi + step_seed) ^ kOrderSalt of this step (Order)
};

enum Receptor { kRecAmpa, kRecNmda, kRecGabaProx, kRecGabaDist };   // their rows of CellArrays::in, in order
#ifdef JAXARM_PROFILE
static_assert(kRecGabaDist + 1 == prof::kReceptors, "one profiling counter per receptor");
#endif

template <Receptor R>
inline float* component(const CellArrays& s) {   // receptor R's component of every cell
  return R == kRecAmpa ? s.ampa : R == kRecNmda ? s.nmda : R == kRecGabaProx ? s.gprox : s.gdist;
}

// The lanes at i: with Threshold, the threshold test of the last step (its input in s.in, its V in s.v) and the
// spikes' effects; with Decay, this step's decay, refractory bookkeeping and V.
template <class T, bool PerEvent, bool OnEvent, bool Order, bool Threshold, bool Decay>
ALWAYS_INLINE void cell_lanes(int64_t i, const CellArrays& s, const CellConstantsView& c) {
  using simd::load;
  typedef typename simd::IntOf<T>::type I;
  const int64_t n = s.n;
  const T rmp = load<T>(c.rmp + i);
  T a = load<T>(s.ampa + i), b = load<T>(s.nmda + i), g = load<T>(s.gprox + i), d = load<T>(s.gdist + i);
  T e = load<T>(s.ahp + i), ex = load<T>(s.excess + i);
  I sn = load<I>(s.since + i);
  const I n_ref = load<I>(c.n_ref + i);
  if constexpr (Threshold) {
    const T vth = load<T>(c.vth + i), vblock = load<T>(c.vblock + i);
    // summed from rmp on, in the one-cell form's order (float addition is not associative: another order moves V
    // in its last bit, and once in a long run a spike with it)
    const T vm = simd::min(simd::max(rmp + a + b + g + d + e, simd::splat<T>(c.vm_min)), simd::splat<T>(c.vm_max));
    auto spike = (sn >= n_ref) & (vm > vth + ex) & (vm <= vblock);
    if constexpr (PerEvent)   // below threshold before this step's input, above Vblock after it: crossed
      spike |= (sn >= n_ref) & (vm > vblock) & (rmp + load<T>(s.v + i) <= vth + ex);
    if constexpr (OnEvent)    // the original tests only on an arriving event
      spike &= (load<T>(s.in + i) != 0.0f) | (load<T>(s.in + n + i) != 0.0f) |
               (load<T>(s.in + 2 * n + i) != 0.0f) | (load<T>(s.in + 3 * n + i) != 0.0f);
    if constexpr (Order) {   // tested in full when set (refractory, threshold, block, inputs, coin)
      spike |= load<I>(s.fires_first + i) != 0;
      simd::store(s.fires_first + i, simd::splat_int<I>(0));
    }
    simd::store_flag(s.spiked + i, spike);
    e = spike ? e - load<T>(c.ahpwt + i) : e;
    ex = spike ? load<T>(c.post_excess + i) : ex;
    sn = spike ? simd::splat_int<I>(0) : sn;
  }
  if constexpr (Decay) {
    a = a * load<T>(c.d_ampa + i);
    b = b * load<T>(c.d_nmda + i);
    g = g * load<T>(c.d_gprox + i);
    d = d * load<T>(c.d_gdist + i);
    e = e * load<T>(c.d_ahp + i);
    sn = simd::min(sn, simd::splat_int<I>(kSinceMax - 1)) + 1;
    const T rr = sn > n_ref ? load<T>(c.d_rr + i) : (sn == n_ref ? load<T>(c.d_rr_first + i) : simd::splat<T>(1.0f));
    ex = ex * rr;
    simd::store(s.v + i, simd::min(simd::max(a + b + g + d + e, rmp), -rmp));
    simd::store(s.ampa + i, a);
    simd::store(s.nmda + i, b);
    simd::store(s.gprox + i, g);
    simd::store(s.gdist + i, d);
  }
  simd::store(s.ahp + i, e);
  simd::store(s.excess + i, ex);
  simd::store(s.since + i, sn);
}

// receptor R's component after this step's input x (loads with Seq, weights without) at V v; a lane without input
// (x == 0) keeps it
template <class T, bool Seq, Receptor R>
ALWAYS_INLINE T jumped(T comp, T v, T x, T rmp, const CellConstantsView& c) {
  const auto has = x != 0.0f;
  if constexpr (R == kRecAmpa) {
    const T ja = Seq ? (c.e_ampa - v) * -fastmath::expm1(x * c.neg_inv_ampa) : x * (1.0f - v * c.inv_ampa);
    return has ? simd::max(comp + ja, simd::splat<T>(0.0f)) : comp;
  } else if constexpr (R == kRecNmda) {
    const T block = 1.0f / (1.0f + fastmath::exp(c.neg_mg_slope * (rmp + v)) * c.mg_ratio);
    return (comp < c.e_nmda) & has ? comp + x * block * (1.0f - v * c.inv_nmda) : comp;
  } else {
    const T jg = Seq ? (v - c.e_gaba) * -fastmath::expm1(x * c.inv_gaba) : x * (1.0f - v * c.inv_gaba);
    return has & (comp > c.e_gaba) ? simd::min(comp - jg, simd::splat<T>(0.0f)) : comp;
  }
}

// Threshold (the last step's test and spikes' effects) and / or Decay (this step's) of every cell
template <bool PerEvent, bool OnEvent, bool Order, bool Threshold, bool Decay>
void cell_pass(const CellArrays& arrays, const CellConstantsView& consts) {
  const CellArrays s = arrays;          // local copies: the stores through s's pointers cannot change them
  const CellConstantsView c = consts;
  const int64_t full = s.n - s.n % simd::kLanes;
  for (int64_t i = 0; i < full; i += simd::kLanes)
    cell_lanes<simd::vf, PerEvent, OnEvent, Order, Threshold, Decay>(i, s, c);
  for (int64_t i = full; i < s.n; ++i) cell_lanes<float, PerEvent, OnEvent, Order, Threshold, Decay>(i, s, c);
}

// direct calls: passing the instantiations through a generic lambda (a function pointer) made the kernel 3.4x
// slower (2026-12-05, benchmarks/network.py at one network: 16 against 56 network-s per CPU-second)
template <bool PerEvent, bool OnEvent, bool Order>
void cell_pass_stages(bool threshold, bool decay, const CellArrays& s, const CellConstantsView& c) {
  if (threshold && decay) cell_pass<PerEvent, OnEvent, Order, true, true>(s, c);
  else if (threshold) cell_pass<PerEvent, OnEvent, Order, true, false>(s, c);
  else cell_pass<PerEvent, OnEvent, Order, false, true>(s, c);
}

template <bool PerEvent>
void cell_pass(bool on_event, bool order, bool threshold, bool decay, const CellArrays& s,
               const CellConstantsView& c) {
  if (on_event) {
    if (order) cell_pass_stages<PerEvent, true, true>(threshold, decay, s, c);
    else cell_pass_stages<PerEvent, true, false>(threshold, decay, s, c);
  } else {
    if (order) cell_pass_stages<PerEvent, false, true>(threshold, decay, s, c);
    else cell_pass_stages<PerEvent, false, false>(threshold, decay, s, c);
  }
}

// The cells among [0, full) with input in x (x != 0, NaN included), in order, into idx (room for full + 8): a mask
// per block of eight and its set lanes' positions from a table, no branch. The profiling build counts the blocks
// with input at receptor R.
const std::array<uint64_t, 256> kSetLanes = [] {
  std::array<uint64_t, 256> t{};
  for (int m = 0; m < 256; ++m)
    for (int b = 0, k = 0; b < 8; ++b)
      if (m >> b & 1) t[m] |= uint64_t(b) << (8 * k++);
  return t;
}();

template <Receptor R>
inline int32_t cells_with_input(const float* __restrict__ x, int64_t full, int32_t* __restrict__ idx) {
  int32_t k = 0;
#ifdef __AVX2__
  for (int64_t i = 0; i < full; i += 8) {
    const int mask = _mm256_movemask_ps(_mm256_cmp_ps(_mm256_loadu_ps(x + i), _mm256_setzero_ps(), _CMP_NEQ_UQ));
    const __m256i lanes = _mm256_cvtepu8_epi32(_mm_cvtsi64_si128(int64_t(kSetLanes[mask])));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(idx + k), _mm256_add_epi32(lanes, _mm256_set1_epi32(int32_t(i))));
    k += __builtin_popcount(mask);
    PROF_COUNT(blocks_with_input[R], mask != 0)
  }
#else
  for (int64_t i = 0; i < full; i += simd::kLanes) {
    const int32_t k0 = k;
    for (int64_t l = i; l < i + simd::kLanes; ++l) {
      idx[k] = int32_t(l);
      k += x[l] != 0.0f;
    }
    PROF_COUNT(blocks_with_input[R], k != k0)
  }
#endif
  return k;
}

// receptor R's jumps of the k cells in idx, eight at a time: their values gathered into lanes, the lanes' results
// stored back (the last lanes of the last eight repeat the last cell, computed and stored twice the same)
template <bool Seq, Receptor R>
ALWAYS_INLINE void jumps_of(const int32_t* __restrict__ idx, int32_t k, float* __restrict__ comp, const float* v,
                            const float* x, const CellConstantsView& c) {
  for (int32_t j = 0; j < k; j += simd::kLanes) {
    int32_t id[simd::kLanes];
    for (int l = 0; l < simd::kLanes; ++l) id[l] = idx[std::min(j + l, k - 1)];
    simd::vf cv, vv, xv, rv = simd::vf{};
    for (int l = 0; l < simd::kLanes; ++l) {
      cv[l] = comp[id[l]];
      vv[l] = v[id[l]];
      xv[l] = x[id[l]];
      if constexpr (R == kRecNmda) rv[l] = c.rmp[id[l]];
    }
    const simd::vf out = jumped<simd::vf, Seq, R>(cv, vv, xv, rv, c);
    for (int l = 0; l < simd::kLanes; ++l) comp[id[l]] = out[l];
  }
}

// Order (same_step_inhibition = "random_order"), cell i with inhibitory input in this step, before its inhibitory
// jumps (the excitatory ones applied): whether its excitation alone passes the threshold test and its coin says the
// excitation came first (cell.cell_step's fires_first, the same tests in the same order). Few cells get past the
// first test (excitatory input in the same step), so this is scalar.
template <bool PerEvent>
inline void flag_fires_first(int64_t i, const CellArrays& s, const CellConstantsView& c) {
  const int64_t n = s.n;
  if ((s.in[i] == 0.0f && s.in[n + i] == 0.0f) || s.since[i] < c.n_ref[i]) return;
  const float vm = std::min(std::max(c.rmp[i] + s.ampa[i] + s.nmda[i] + s.gprox[i] + s.gdist[i] + s.ahp[i], c.vm_min),
                            c.vm_max);
  const float thr = c.vth[i] + s.excess[i];
  if (!(vm > thr) || !(vm <= c.vblock[i] || (PerEvent && c.rmp[i] + s.v[i] <= thr))) return;
  if (hash32(s.lane_key[i] ^ s.order_s) >> 31) s.fires_first[i] = 1;
}

// Receptor R's jumps in this step: its cells with input listed, their jumps computed eight at a time, then the last
// n % kLanes cells one at a time. Order: the listed cells' fires_first flags first (at GABA-dist only the cells
// without GABA-prox input, whose flags the GABA-prox pass set from the same V).
template <bool Seq, bool PerEvent, bool Order, Receptor R>
ALWAYS_INLINE void receptor_jumps(const CellArrays& s, const CellConstantsView& c) {
  const int64_t n = s.n;
  const int64_t full = n - n % simd::kLanes;
  const float* x = s.in + int64_t(R) * n;
  float* comp = component<R>(s);
  const int32_t k = cells_with_input<R>(x, full, s.listed);
  constexpr bool kCheck = Order && (R == kRecGabaProx || R == kRecGabaDist);
  const float* prox = s.in + int64_t(kRecGabaProx) * n;
  if constexpr (kCheck)
    for (int32_t j = 0; j < k; ++j)
      if (R == kRecGabaProx || prox[s.listed[j]] == 0.0f) flag_fires_first<PerEvent>(s.listed[j], s, c);
  jumps_of<Seq, R>(s.listed, k, comp, s.v, x, c);
  for (int64_t i = full; i < n; ++i) {
    if (x[i] == 0.0f) continue;
    if constexpr (kCheck)
      if (R == kRecGabaProx || prox[i] == 0.0f) flag_fires_first<PerEvent>(i, s, c);
    comp[i] = jumped<float, Seq, R>(comp[i], s.v[i], x[i], c.rmp[i], c);
  }
}

// This step's jumps, once its input is complete. In the paper's network 3-8 % of the cells have input at a
// receptor in a step (half of the blocks of eight have AMPA input, a quarter NMDA, a fifth to a quarter each GABA:
// block_input_share in docs/results/profile.json), so the cells with input are listed per receptor and their
// jumps, whose transcendental functions are most of the cost, computed eight listed cells at a time. Every cell
// takes exactly the operations of the one-cell form, so the bits are those of computing every jump densely (the
// receptors' components are independent: their order does not matter).
template <bool Seq, bool PerEvent, bool Order>
void jumps(const CellArrays& arrays, const CellConstantsView& consts) {
  const CellArrays s = arrays;
  const CellConstantsView c = consts;
  PROF_COUNT(cell_blocks, s.n / simd::kLanes)
  receptor_jumps<Seq, PerEvent, Order, kRecAmpa>(s, c);
  receptor_jumps<Seq, PerEvent, Order, kRecNmda>(s, c);
  receptor_jumps<Seq, PerEvent, Order, kRecGabaProx>(s, c);
  receptor_jumps<Seq, PerEvent, Order, kRecGabaDist>(s, c);
}

template <bool PerEvent>
void run_network(const std::vector<View>& in, const std::vector<View>& out, const std::vector<int64_t>& idx,
                 int64_t flat, const Attrs& a) {
  auto I = [&](int k) { return batch_offset(in[k], idx); };
  const int64_t n = in[kAmpa].per_network;
  const int64_t n_p = in[kPNext].per_network;
  const int64_t n_all = in[kLast].per_network;
  const int64_t p_start = n_all - n_p;
  const int64_t kmax = in[kThresholds].per_network / (3 * n);
  const int64_t n_syn = in[kWgain].per_network;
  const int64_t n_plastic = in[kPdope].per_network;
  const int64_t n_psyn = in[kPPre].per_network;
  const int64_t width = 4 * n;
  PROF_START

  // Copy the state into the outputs, then update the outputs in place.
  static const int copies[][2] = {{kAmpa, oAmpa}, {kNmda, oNmda}, {kGabaProx, oGabaProx}, {kGabaDist, oGabaDist},
                                  {kAhp, oAhp}, {kExcess, oExcess}, {kSince, oSince}, {kPNext, oPNext},
                                  {kRing, oRing}, {kPdope, oPdope}, {kLast, oLast}, {kPrev, oPrev},
                                  {kCount, oCount}, {kEventsLeft, oEventsLeft}};
  for (const auto& c : copies) {
    const View& src = in[c[0]];
    const View& dst = out[c[1]];
    char* d = dst.data + flat * dst.per_network * dst.elem;
    const char* s = src.data + I(c[0]) * src.per_network * src.elem;
    if (d != s) std::memcpy(d, s, dst.per_network * dst.elem);
  }
  float* __restrict__ ampa = at<float>(out[oAmpa], flat);
  float* __restrict__ nmda = at<float>(out[oNmda], flat);
  float* __restrict__ gprox = at<float>(out[oGabaProx], flat);
  float* __restrict__ gdist = at<float>(out[oGabaDist], flat);
  float* __restrict__ ahp = at<float>(out[oAhp], flat);
  float* __restrict__ excess = at<float>(out[oExcess], flat);
  int32_t* __restrict__ since = at<int32_t>(out[oSince], flat);
  int32_t* __restrict__ p_next = at<int32_t>(out[oPNext], flat);
  float* __restrict__ ring = at<float>(out[oRing], flat);
  float* __restrict__ pdope = at<float>(out[oPdope], flat);
  float* __restrict__ last = at<float>(out[oLast], flat);
  float* __restrict__ prev = at<float>(out[oPrev], flat);
  int32_t* __restrict__ count = at<int32_t>(out[oCount], flat);
  int32_t* __restrict__ events_left = at<int32_t>(out[oEventsLeft], flat);
  bool* spikes = at<bool>(out[oSpikes], flat);

  const int32_t first_step = *at<int32_t>(in[kStep], I(kStep));
  const int32_t* p_interval = at<int32_t>(in[kPInterval], I(kPInterval));
  const uint32_t step_seed = *at<uint32_t>(in[kStepSeed], I(kStepSeed));
  const uint32_t* lane_key = at<uint32_t>(in[kLaneKey], I(kLaneKey));
  const uint32_t* thr = at<uint32_t>(in[kThresholds], I(kThresholds));
  const float* wgain = at<float>(in[kWgain], I(kWgain));
  const float window_ms = *at<float>(in[kWindow], I(kWindow));
  const int32_t* p_pre = at<int32_t>(in[kPPre], I(kPPre));
  const int32_t* p_delay = at<int32_t>(in[kPDelay], I(kPDelay));
  const int32_t* p_target = at<int32_t>(in[kPTarget], I(kPTarget));
  const float* p_weight = at<float>(in[kPWeight], I(kPWeight));
  const int32_t* p_syn = at<int32_t>(in[kPSyn], I(kPSyn));   // synapse id of each generator synapse
  const float* p_nmda = at<float>(in[kPNmda], I(kPNmda));
  const float* cf = at<float>(in[kCellF], I(kCellF));
  const float *rmp = cf, *vth = cf + n, *vblock = cf + 2 * n, *ahpwt = cf + 3 * n, *post_excess = cf + 4 * n,
              *d_ampa = cf + 5 * n, *d_nmda = cf + 6 * n, *d_gprox = cf + 7 * n, *d_gdist = cf + 8 * n,
              *d_ahp = cf + 9 * n, *d_rr = cf + 10 * n, *d_rr_first = cf + 11 * n;
  const int32_t* n_ref = at<int32_t>(in[kNRef], I(kNRef));
  const float* noise_w = at<float>(in[kNoiseW], I(kNoiseW));
  const int32_t* cell_group = at<int32_t>(in[kCellGroup], I(kCellGroup));
  const int32_t* cell_row = at<int32_t>(in[kCellRow], I(kCellRow));

  struct Tables {
    const int32_t *out_syn, *out_packed;
    const float *out_weight, *out_nmda;
    const int32_t *in_plastic, *in_pre;
    int64_t out_width, in_width;
  };
  std::vector<Tables> groups(a.n_groups);
  for (int64_t g = 0; g < a.n_groups; ++g) {
    const int base = kGroupTables + kTablesPerGroup * g;
    groups[g] = Tables{at<int32_t>(in[base], I(base)), at<int32_t>(in[base + 1], I(base + 1)),
                       at<float>(in[base + 2], I(base + 2)), at<float>(in[base + 3], I(base + 3)),
                       at<int32_t>(in[base + 4], I(base + 4)), at<int32_t>(in[base + 5], I(base + 5)), 0, 0};
  }
  // Row widths: per-network element count / rows, rows = that group's cell count + 1.
  {
    std::vector<int64_t> rows(a.n_groups, 1);
    for (int64_t i = 0; i < n; ++i) rows[cell_group[i]] += 1;
    for (int64_t g = 0; g < a.n_groups; ++g) {
      const int base = kGroupTables + kTablesPerGroup * g;
      groups[g].out_width = in[base].per_network / rows[g];
      groups[g].in_width = in[base + 4].per_network / rows[g];
    }
  }

  const int64_t n_slots = a.n_slots;
  const int64_t n_steps = a.n_steps;
  const float dt = a.dt_ms;
  const bool seq = a.sequential != 0;
  const float e_ampa = a.e_ampa, e_nmda = a.e_nmda, e_gaba = a.e_gaba, jump_cap = a.max_jump_fraction;
  const float neg_inv_ampa = -1.0f / e_ampa, inv_gaba = 1.0f / e_gaba, inv_ampa = 1.0f / e_ampa;
  const float inv_nmda = 1.0f / e_nmda, neg_mg_slope = -a.mg_slope, mg_ratio = a.mg / a.mg0;
  const int delay_bits = int(a.delay_bits);
  const int32_t delay_mask = (int32_t(1) << delay_bits) - 1;

  PROF_MARK(kCopyIn)
  // 1. generator (P) input of every generator spike in (first_step, first_step + n_steps].
  {
    const int64_t last_step = int64_t(first_step) + n_steps;
    for (int64_t k = 0; k < n_psyn; ++k) {
      const int32_t pre = p_pre[k];
      int64_t spike = p_next[pre];
      if (spike > last_step) continue;
      float w = p_weight[k] * wgain[p_syn[k]];
      if (seq) w = event_load(w, e_ampa, jump_cap);
      const int32_t interval = p_interval[pre];
      while (spike <= last_step) {
        if (spike > first_step) {
          const int64_t idx = ((spike + p_delay[k]) % n_slots) * width + p_target[k];
          ring[idx] += w;
          ring[idx + n] += p_nmda[k];
        }
        if (interval >= kNever) break;
        spike += interval;
      }
    }
  }

  // Per-step scratch. The step is split into passes the compiler vectorises (noise, the cells) and scalar passes
  // over the spikes (a few per step).
  std::vector<uint32_t> u_buf(n);
  std::vector<int32_t> noise_blocks(n / simd::kLanes + 1);
  // byte flags, padded to whole 8-byte words (zero) so they can be scanned a word at a time
  std::vector<uint8_t> spk_buf(n + 8, 0);
  std::vector<float> v_buf(n);
  std::vector<int32_t> listed_buf(n + simd::kLanes);
  std::vector<int32_t> first_buf(n, 0);   // fires_first (random_order)
  const bool order = a.random_order != 0;
  std::vector<int32_t> fired;
  fired.reserve(n);
  const CellConstantsView cc{rmp,      vth,      vblock,       ahpwt,    post_excess, d_ampa,  d_nmda,
                             d_gprox,  d_gdist,  d_ahp,        d_rr,     d_rr_first,  n_ref,   e_ampa,
                             a.e_nmda, e_gaba,   neg_inv_ampa, inv_gaba, inv_ampa,    inv_nmda, neg_mg_slope,
                             mg_ratio, a.vm_min, a.vm_max};
  // a fired cell's row of weights (loads), gathered then converted vectorised
  int64_t max_width = 0;
  for (const Tables& tb : groups) max_width = std::max(max_width, tb.out_width);
  std::vector<float> row_buf(max_width);
  float* __restrict__ row_w = row_buf.data();
  uint32_t* __restrict__ ub = u_buf.data();
  uint8_t* __restrict__ sb = spk_buf.data();

  const bool limited = any_limited(3 * n, events_left);  // the test's EM noise, or nothing to spend
  PROF_MARK(kPWindow)
  PROF_COUNT(steps, n_steps)
  // Step t's cells are updated in two parts: its decay in the pass that also tests the threshold of step t - 1,
  // its jumps once its input is complete; so the loop runs one extra time for the last step's threshold test.
  float* __restrict__ prev_inb = nullptr;   // the input of step t - 1 (its threshold test reads it: on_event)
  for (int64_t t = 0; t <= n_steps; ++t) {
    const bool this_step = t < n_steps, last_step = t > 0;
    const int32_t m = first_step + int32_t(t) + 1;
    // 2a. this step's slot of the ring
    // (used in place as this step's input and cleared after its threshold test: nothing is delivered into it
    // meanwhile, every delay being at least one step and shorter than the ring)
    const int64_t m_slot = int64_t(m) % n_slots;
    float* __restrict__ inb = ring + m_slot * width;
    if (a.batched && this_step) {   // the next step's slot on its way into the cache while this step runs: in a
                       // batch, a network's ring has left the cache since its last chunk (alone, it stays;
                       // prefetching it there measured 3 % slower)
      const char* next = reinterpret_cast<const char*>(ring + (m_slot + 1 == n_slots ? 0 : m_slot + 1) * width);
      for (int64_t b = 0; b < int64_t(sizeof(float)) * width; b += 64) __builtin_prefetch(next + b, 1, 3);
    }
    // 2c. the threshold test of step t - 1 and its spikes' effects on the cells; the decay and V of step t
    cell_pass<PerEvent>(a.on_event != 0, order, last_step, this_step,
                        CellArrays{ampa, nmda, gprox, gdist, ahp, excess, since, prev_inb, v_buf.data(),
                                   listed_buf.data(), sb, n, first_buf.data(), lane_key, 0},
                        cc);
    PROF_MARK(kCells)
    if (last_step) {   // 2d-g. the spikes of step t - 1
      const int64_t tp = t - 1;
      const int32_t mp = m - 1;
      const float t_ms = float(mp) * dt;
      const int64_t mp_slot = int64_t(mp) % n_slots;
      fired.clear();
      for (int64_t i0 = 0; i0 < n; i0 += 8) {
        uint64_t word;
        std::memcpy(&word, sb + i0, 8);
        if (word == 0) continue;
        for (int64_t i = i0; i < std::min(i0 + 8, n); ++i)
          if (sb[i]) fired.push_back(int32_t(i));
      }
      std::memset(prev_inb, 0, sizeof(float) * width);
      // 2e. spike output, last / previous spike times and counts; P trains
      bool* out_spk = spikes + tp * n_all;
      std::memset(out_spk, 0, n_all);
      for (int32_t i : fired) {
        out_spk[i] = true;
        prev[i] = last[i];
        last[i] = t_ms;
        count[i] += 1;
      }
      for (int64_t j0 = 0; j0 < n_p; j0 += simd::kLanes) {
        if (j0 + simd::kLanes <= n_p && !simd::any(simd::load<simd::vi>(p_next + j0) == mp))
          continue;   // no P spike now in these eight
        for (int64_t j = j0; j < std::min(j0 + simd::kLanes, n_p); ++j) {
          if (p_next[j] != mp) continue;
          const int64_t id = p_start + j;
          out_spk[id] = true;
          prev[id] = last[id];
          last[id] = t_ms;
          count[id] += 1;
          p_next[j] = p_interval[j] >= kNever ? kNever : p_next[j] + p_interval[j];
        }
      }
      PROF_MARK(kSpikeBookkeeping)
      PROF_COUNT(spikes, int64_t(fired.size()))
      // 2f. delivery of the network spikes
      for (int32_t i : fired) {
        const Tables& tb = groups[cell_group[i]];
        const bool exc = a.exc[cell_group[i]] != 0;
        const float e_rev = exc ? e_ampa : -e_gaba;
        const int64_t r = cell_row[i];
        const int32_t* syn = tb.out_syn + r * tb.out_width;
        const int32_t* packed = tb.out_packed + r * tb.out_width;
        const float* wt = tb.out_weight + r * tb.out_width;
        const float* wn = tb.out_nmda + r * tb.out_width;
        PROF_COUNT(synapse_events, tb.out_width)
        const int64_t wd = tb.out_width;
        for (int64_t j = 0; j < wd; ++j) row_w[j] = syn[j] < n_syn ? wt[j] * wgain[syn[j]] : 0.0f;  // padding: 0
        if (seq) {
          int64_t j = 0;
          for (; j + simd::kLanes <= wd; j += simd::kLanes)
            simd::store(row_w + j, event_load(simd::load<simd::vf>(row_w + j), e_rev, jump_cap));
          for (; j < wd; ++j) row_w[j] = event_load(row_w[j], e_rev, jump_cap);
        }
        for (int64_t j = 0; j < wd; ++j) {
          if (syn[j] >= n_syn) continue;  // padding
          // slot (mp + delay) % n_slots without a division per synapse: delay < n_slots (Network.n_slots)
          const int64_t slot = mp_slot + (packed[j] & delay_mask);
          const int64_t idx = (slot >= n_slots ? slot - n_slots : slot) * width + (packed[j] >> delay_bits);
          ring[idx] += row_w[j];
          if (exc) ring[idx + n] += wn[j];
        }
      }
      PROF_MARK(kDelivery)
      // 2g. tagging of the plastic inputs of every cell that fired (reads spike times, writes tags: independent of
      // the ring, so its own loop gives the same results)
      if (n_plastic > 0)
        for (int32_t i : fired) {
          const Tables& tb = groups[cell_group[i]];
          const int64_t r = cell_row[i];
          const int32_t* tag = tb.in_plastic + r * tb.in_width;
          const int32_t* pre = tb.in_pre + r * tb.in_width;
          PROF_COUNT(tag_checks, tb.in_width)
          for (int64_t j = 0; j < tb.in_width; ++j) {
            if (tag[j] >= n_plastic || pre[j] >= n_all) continue;
            const float l = last[pre[j]] <= t_ms ? last[pre[j]] : prev[pre[j]];
            if (l >= 0.0f && t_ms - l <= window_ms) pdope[tag[j]] = std::max(pdope[tag[j]], t_ms);
          }
        }
      PROF_MARK(kTags)
    }
    if (!this_step) break;
    // 2b. noise counts N = #{k : u >= T_k}, added as count x weight to the AMPA, GABA-prox, GABA-dist inputs (after
    // the last step's delivery, which may land in this step's slot: the same order of additions as the XLA path)
    const uint32_t step_hash = hash32(uint32_t(m) * kGolden + step_seed);
    add_noise(n, kmax, step_hash, lane_key, thr, noise_w, events_left, limited, inb, ub, noise_blocks.data());
    PROF_MARK(kNoise)
    // 2c. this step's jumps
    const CellArrays cells{ampa, nmda,       gprox,   gdist, ahp, excess,           since,   inb,
                           v_buf.data(),     listed_buf.data(), sb, n, first_buf.data(), lane_key,
                           step_hash ^ kOrderSalt};
    if (seq) order ? jumps<true, PerEvent, true>(cells, cc) : jumps<true, PerEvent, false>(cells, cc);
    else order ? jumps<false, PerEvent, true>(cells, cc) : jumps<false, PerEvent, false>(cells, cc);
    PROF_MARK(kCells)
    prev_inb = inb;
  }
  *at<int32_t>(out[oStep], flat) = first_step + int32_t(n_steps);
}

View view_of(const ffi::AnyBuffer& b, int base_rank, int batch_rank) {
  auto dims = b.dimensions();
  View v;
  v.data = static_cast<char*>(b.untyped_data());
  v.elem = int64_t(ffi::ByteWidth(b.element_type()));
  v.per_network = 1;
  for (int64_t d = int64_t(dims.size()) - base_rank; d < int64_t(dims.size()); ++d) v.per_network *= dims[d];
  for (int d = 0; d < batch_rank; ++d) v.batch_dims.push_back(dims[d]);
  return v;
}

ffi::Error ChunkImpl(ffi::RemainingArgs args, ffi::RemainingRets rets, int64_t n_steps, int64_t n_slots,
                     int64_t sequential, int64_t on_event, int64_t per_event, int64_t random_order, float dt_ms,
                     ffi::Span<const int64_t> excitatory, int64_t n_threads, float e_ampa_mv, float e_nmda_mv,
                     float e_gaba_mv, float mg_mm, float mg0_mm, float mg_slope_per_mv, float vm_min_mv,
                     float vm_max_mv, float max_jump_fraction, int64_t delay_bits) {
  const int64_t n_groups = int64_t(excitatory.size());
  const int64_t n_in = kGroupTables + kTablesPerGroup * n_groups;
  if (int64_t(args.size()) != n_in || int64_t(rets.size()) != kNumOut || n_groups > 8)
    return ffi::Error::InvalidArgument("jaxarm chunk kernel: wrong number of arguments or results");
  auto step0 = args.get<ffi::AnyBuffer>(0);
  if (step0.has_error()) return step0.error();
  const int batch_rank = int(step0->dimensions().size());
  std::vector<View> in(n_in), out(kNumOut);
  for (int64_t k = 0; k < n_in; ++k) {
    auto b = args.get<ffi::AnyBuffer>(k);
    if (b.has_error()) return b.error();
    const int base = k < kGroupTables ? kBaseRankFixed[k] : 2;
    if (int(b->dimensions().size()) != base + batch_rank)
      return ffi::Error::InvalidArgument("jaxarm chunk kernel: input " + std::to_string(k) + " has rank " +
                                         std::to_string(b->dimensions().size()) + ", expected " +
                                         std::to_string(base + batch_rank));
    in[k] = view_of(*b, base, batch_rank);
  }
  std::vector<int64_t> batch(batch_rank, 1);
  for (const View& v : in)
    for (int d = 0; d < batch_rank; ++d) batch[d] = std::max(batch[d], v.batch_dims[d]);
  for (int64_t k = 0; k < kNumOut; ++k) {
    auto r = rets.get<ffi::AnyBuffer>(k);
    if (r.has_error()) return r.error();
    out[k] = view_of(**r, kBaseRankOut[k], batch_rank);
  }
  Attrs a{n_steps,   n_slots,   n_groups, sequential, on_event,        per_event, random_order, {0},
          dt_ms,     e_ampa_mv, e_nmda_mv,    e_gaba_mv, mg_mm,     mg0_mm,   mg_slope_per_mv, vm_min_mv,
          vm_max_mv, max_jump_fraction, delay_bits};
  for (int64_t g = 0; g < n_groups; ++g) a.exc[g] = excitatory[g];
  int64_t total = 1;
  for (int64_t b : batch) total *= b;
  a.batched = total > 1;

  auto work = [&](int64_t lo, int64_t hi) {
    std::vector<int64_t> idx(batch_rank);
    for (int64_t f = lo; f < hi; ++f) {
      int64_t rem = f;
      for (int d = batch_rank - 1; d >= 0; --d) {
        idx[d] = rem % batch[d];
        rem /= batch[d];
      }
      if (a.per_event) run_network<true>(in, out, idx, f, a);
      else run_network<false>(in, out, idx, f, a);
    }
  };
  const int64_t threads = std::max<int64_t>(1, std::min(n_threads, total));
  if (threads == 1) {
    work(0, total);
  } else {
    std::vector<std::thread> pool;
    for (int64_t t = 0; t < threads; ++t)
      pool.emplace_back(work, total * t / threads, total * (t + 1) / threads);
    for (auto& th : pool) th.join();
  }
  return ffi::Error::Success();
}

}  // namespace

// fastmath for tests (tests/test_native_math.py): out[i] = f(x[i]) with f = exp (0), expm1 (1), log1p (2), one
// float at a time; which + 3: the same in blocks of eight lanes (n a multiple of eight), the kernel's vector path
extern "C" void JaxarmFastMath(const float* x, float* out, int64_t n, int64_t which) {
  if (which < 3) {
    for (int64_t i = 0; i < n; ++i)
      out[i] = which == 0 ? fastmath::exp(x[i]) : which == 1 ? fastmath::expm1(x[i]) : fastmath::log1p(x[i]);
    return;
  }
  for (int64_t i = 0; i + simd::kLanes <= n; i += simd::kLanes) {
    const simd::vf v = simd::load<simd::vf>(x + i);
    simd::store(out + i, which == 3 ? fastmath::exp(v) : which == 4 ? fastmath::expm1(v) : fastmath::log1p(v));
  }
}

XLA_FFI_DEFINE_HANDLER_SYMBOL(JaxarmNetworkChunk, ChunkImpl,
                              ffi::Ffi::Bind()
                                  .RemainingArgs()
                                  .RemainingRets()
                                  .Attr<int64_t>("n_steps")
                                  .Attr<int64_t>("n_slots")
                                  .Attr<int64_t>("sequential")
                                  .Attr<int64_t>("on_event")
                                  .Attr<int64_t>("per_event")
                                  .Attr<int64_t>("random_order")
                                  .Attr<float>("dt_ms")
                                  .Attr<ffi::Span<const int64_t>>("excitatory")
                                  .Attr<int64_t>("n_threads")
                                  .Attr<float>("e_ampa_mv")
                                  .Attr<float>("e_nmda_mv")
                                  .Attr<float>("e_gaba_mv")
                                  .Attr<float>("mg_mm")
                                  .Attr<float>("mg0_mm")
                                  .Attr<float>("mg_slope_per_mv")
                                  .Attr<float>("vm_min_mv")
                                  .Attr<float>("vm_max_mv")
                                  .Attr<float>("max_jump_fraction")
                                  .Attr<int64_t>("delay_bits"));
