/// \file vector_pass.cpp
/// The neighbour search's candidate passes with AVX-512 (vector_pass.hpp),
/// compiled for that instruction set alone and called only where the
/// processor has it.
#include "vector_pass.hpp"

#include <atomic>

#include "frame.hpp"

#if BROADPHASE_NEIGHBOURS_AVX512
#include <immintrin.h>
#endif

namespace broadphase::neighbours_detail {

namespace {
std::atomic<bool> vector_search_wanted{true};
}  // namespace

bool vector_search_available() {
#if BROADPHASE_NEIGHBOURS_AVX512
  static const bool has = __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl");
  return has;
#else
  return false;
#endif
}

bool vector_search() { return vector_search_wanted.load() && vector_search_available(); }

void allow_vector_search(bool allow) { vector_search_wanted.store(allow); }

#if BROADPHASE_NEIGHBOURS_AVX512
namespace {

/// The vector passes' test of slots [q, q + 8) (those of mask `m`) against
/// a point at `qx, qy, qz` (the point moved by the run's offset, px - off,
/// as the scalar loop computes it), in the scalar loop's double arithmetic
/// (a fused multiply-add may round a distance differently by an ulp: the
/// margin covers a few): the lanes within reach, those also inside the
/// inner reach, and the slots' ids. `one` selects the one cutoff's squared
/// reaches; otherwise each pair's from cp and the slots' cutoffs.
struct Lanes {
  __mmask8 in, inside;
  __m256i ids;
};

struct Reaches {
  bool one;
  __m512d reach2, inner2;  // the one cutoff's
  __m512d cp, margin;      // per-point cutoffs: the point's, and the margin
};

__attribute__((target("avx512f,avx512vl"))) inline Reaches vectors_of(const VectorReaches& v) {
  return {v.one, _mm512_set1_pd(v.reach2), _mm512_set1_pd(v.inner2), _mm512_set1_pd(v.cp),
          _mm512_set1_pd(v.margin)};
}

__attribute__((target("avx512f,avx512vl"))) inline Lanes test_eight(const Binned& b,
                                                                    std::uint32_t q, __mmask8 m,
                                                                    __m512d qx, __m512d qy,
                                                                    __m512d qz, const Reaches& r) {
  const __m512d dx = _mm512_sub_pd(_mm512_maskz_loadu_pd(m, b.wx.data() + q), qx);
  const __m512d dy = _mm512_sub_pd(_mm512_maskz_loadu_pd(m, b.wy.data() + q), qy);
  const __m512d dz = _mm512_sub_pd(_mm512_maskz_loadu_pd(m, b.wz.data() + q), qz);
  const __m512d d2 = _mm512_add_pd(_mm512_add_pd(_mm512_mul_pd(dx, dx), _mm512_mul_pd(dy, dy)),
                                   _mm512_mul_pd(dz, dz));
  __m512d reach2 = r.reach2, inner2 = r.inner2;
  if (!r.one) {
    const __m512d sum = _mm512_add_pd(r.cp, _mm512_maskz_loadu_pd(m, b.wc.data() + q));
    const __m512d reach = _mm512_add_pd(sum, r.margin);
    const __m512d inner =
        _mm512_maskz_max_pd(0xff, _mm512_sub_pd(sum, r.margin), _mm512_setzero_pd());
    reach2 = _mm512_mul_pd(reach, reach);
    inner2 = _mm512_mul_pd(inner, inner);
  }
  Lanes l;
  l.in = _mm512_mask_cmp_pd_mask(m, d2, reach2, _CMP_LE_OQ);
  l.inside = _mm512_mask_cmp_pd_mask(l.in, d2, inner2, _CMP_LT_OQ);
  l.ids = _mm256_maskz_loadu_epi32(m, b.id.data() + q);
  return l;
}

/// The vector passes' walk: calls eight(q, m, qx, qy, qz, k) for the
/// slots of each run k, eight at a time.
template <class Eight>
__attribute__((target("avx512f,avx512vl"))) inline void each_eight(const std::vector<Run>& runs,
                                                                   double px, double py, double pz,
                                                                   Eight&& eight) {
  for (std::size_t k = 0; k < runs.size(); ++k) {
    const Run& run = runs[k];
    const __m512d qx = _mm512_set1_pd(px - run.off.x), qy = _mm512_set1_pd(py - run.off.y),
                  qz = _mm512_set1_pd(pz - run.off.z);
    for (std::uint32_t q = run.lo; q < run.hi; q += 8) {
      const std::uint32_t left = run.hi - q;
      eight(q, static_cast<__mmask8>(left >= 8 ? 0xffu : (1u << left) - 1), qx, qy, qz, k);
    }
  }
}

/// `picks` (run << 32 | slot) of the lanes of `keep`, stored whole after a
/// compress in a register (a compressing store to memory is microcoded on
/// some processors): writes up to 8 entries past them.
__attribute__((target("avx512f,avx512vl"))) inline void store_picks(std::uint64_t* pick,
                                                                    std::size_t& picked,
                                                                    __mmask8 keep, std::size_t k,
                                                                    std::uint32_t q) {
  const __m512i refs =
      _mm512_add_epi64(_mm512_set1_epi64(static_cast<long long>(std::uint64_t{k} << 32 | q)),
                       _mm512_set_epi64(7, 6, 5, 4, 3, 2, 1, 0));
  _mm512_storeu_si512(pick + picked, _mm512_maskz_compress_epi64(keep, refs));
  picked += static_cast<std::size_t>(__builtin_popcount(keep));
}

}  // namespace

/// The self search's candidate pass with AVX-512, eight candidates at a
/// time: the picks the scalar loop in find_self_part makes, in its order.
/// At 10^6 points the search took 165 ms instead of 197 on one thread (the
/// scalar loop goes one candidate at a time, at about 11 cycles each).
/// Tried and not kept: sixteen candidates a turn to spare the runs' loop
/// exits, a bin's chunks in one loop a point, marking the candidates inside
/// the inner reach for the pick loop (slower or no faster).
__attribute__((target("avx512f,avx512vl"))) std::size_t pick_avx512(
    const Binned& b, const std::vector<Run>& runs, double px, double py, double pz,
    const VectorReaches& v, std::uint32_t ip, bool full, std::uint64_t* pick) {
  const Reaches r = vectors_of(v);
  std::size_t picked = 0;
  const __m256i mine = _mm256_set1_epi32(static_cast<int>(ip));
  each_eight(
      runs, px, py, pz,
      [&](std::uint32_t q, __mmask8 m, __m512d qx, __m512d qy, __m512d qz, std::size_t k)
          __attribute__((target("avx512f,avx512vl"))) {
            const Lanes l = test_eight(b, q, m, qx, qy, qz, r);
            const __mmask8 keep =
                full ? l.in : _mm256_mask_cmp_epu32_mask(l.in, l.ids, mine, _MM_CMPINT_NLT);
            store_picks(pick, picked, keep, k, q);
          });
  return picked;
}

/// The self search's pass for packed records when every point lies in the
/// cell (wrap counts all zero, so a pair's shift is its run's): a candidate
/// inside the inner reach whose record the point keeps (a larger index in a
/// half list, another index in a full one) is written as its record at
/// `keys`; the others within reach that the scalar loop would pick (self
/// images, the point itself, the rim between the inner and outer reach) go
/// to `pick` for the pick loop. Writes up to 8 entries past each. Returns
/// the records written; `picked` counts the picks. At 10^6 points the
/// list took 0.27 s instead of 0.29 on one thread, 0.16 instead of 0.18 on
/// two: the pick loop spends a branch or two on each kept pair.
__attribute__((target("avx512f,avx512vl"))) std::size_t records_avx512(
    const Binned& b, const std::vector<Run>& runs, double px, double py, double pz,
    const VectorReaches& v, std::uint32_t ip, bool full, PackedFound* keys, std::uint64_t* pick,
    std::size_t& picked) {
  const Reaches r = vectors_of(v);
  std::size_t written = 0;
  picked = 0;
  const __m256i mine = _mm256_set1_epi32(static_cast<int>(ip));
  std::size_t shift_of = runs.size();
  __m512i shift = _mm512_setzero_si512();
  each_eight(
      runs, px, py, pz,
      [&](std::uint32_t q, __mmask8 m, __m512d qx, __m512d qy, __m512d qz, std::size_t k)
          __attribute__((target("avx512f,avx512vl"))) {
            if (k != shift_of) {
              const std::int64_t s[3] = {runs[k].sb[0], runs[k].sb[1], runs[k].sb[2]};
              shift = _mm512_set1_epi64(static_cast<long long>(PackedFound::make(0, s).key));
              shift_of = k;
            }
            const Lanes l = test_eight(b, q, m, qx, qy, qz, r);
            const __mmask8 kept =
                full ? _mm256_mask_cmp_epu32_mask(l.inside, l.ids, mine, _MM_CMPINT_NE)
                     : _mm256_mask_cmp_epu32_mask(l.inside, l.ids, mine, _MM_CMPINT_GT);
            const __mmask8 rest =
                l.in & static_cast<__mmask8>(~kept) &
                (full ? l.in : _mm256_mask_cmp_epu32_mask(l.in, l.ids, mine, _MM_CMPINT_NLT));
            const __m512i records = _mm512_or_si512(
                _mm512_maskz_slli_epi64(0xff, _mm512_maskz_cvtepu32_epi64(0xff, l.ids), 32), shift);
            _mm512_storeu_si512(keys + written, _mm512_maskz_compress_epi64(kept, records));
            written += static_cast<std::size_t>(__builtin_popcount(kept));
            store_picks(pick, picked, rest, k, q);
          });
  return written;
}

#endif

}  // namespace broadphase::neighbours_detail
