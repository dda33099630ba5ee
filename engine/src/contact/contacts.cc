#include "activefoam/contacts.h"

#include <algorithm>
#include <array>
#include <cstdint>
#include <stdexcept>
#include <type_traits>

#include "activefoam/threads.h"

namespace activefoam {

int contactParts(std::size_t num_pairs) {
  return static_cast<std::int64_t>(num_pairs) > grain().min_items ? threads() : 1;
}

void ContactPartition::build(const std::vector<ContactPair>& pairs,
                             const std::vector<int>& tri_cell, int num_cells, int n_parts) {
  num_pairs = pairs.size();
  parts = std::max(1, n_parts);
  begin.assign(static_cast<std::size_t>(parts) + 1, 0);
  item.clear();
  if (parts == 1) return;
  // Counted over `parts` consecutive ranges of pairs, one per thread, and combined in range order:
  // the items of each part stay in pair order, as a serial pass would leave them.
  const int R = parts;
  const auto range = [&](int r) {
    return std::pair<std::size_t, std::size_t>{num_pairs * r / R, num_pairs * (r + 1) / R};
  };
  // Cells to parts by the running count of pair sides, so that the parts' work is about equal;
  // the bits do not depend on the split.
  std::vector<std::int64_t> range_load(static_cast<std::size_t>(R) * num_cells, 0);
#pragma omp parallel for schedule(static, 1)
  for (int r = 0; r < R; ++r) {
    std::int64_t* load = &range_load[static_cast<std::size_t>(r) * num_cells];
    const auto [b, e] = range(r);
    for (std::size_t q = b; q < e; ++q) {
      ++load[tri_cell[pairs[q].ta]];
      ++load[tri_cell[pairs[q].tb]];
    }
  }
  const std::int64_t total = std::max<std::int64_t>(1, 2 * static_cast<std::int64_t>(num_pairs));
  std::vector<int> cell_part(static_cast<std::size_t>(num_cells));
  std::int64_t before = 0;
  for (int c = 0; c < num_cells; ++c) {
    std::int64_t load = 0;
    for (int r = 0; r < R; ++r) load += range_load[static_cast<std::size_t>(r) * num_cells + c];
    cell_part[c] =
        static_cast<int>(std::min<std::int64_t>(parts - 1, (before + load / 2) * parts / total));
    before += load;
  }
  auto sides = [&](const ContactPair& p) {
    return std::pair{cell_part[tri_cell[p.ta]], cell_part[tri_cell[p.tb]]};
  };
  // fill[r * parts + k]: where range r's first item of part k goes.
  std::vector<std::int64_t> fill(static_cast<std::size_t>(R) * parts, 0);
#pragma omp parallel for schedule(static, 1)
  for (int r = 0; r < R; ++r) {
    std::int64_t* count = &fill[static_cast<std::size_t>(r) * parts];
    const auto [b, e] = range(r);
    for (std::size_t q = b; q < e; ++q) {
      const auto [pa, pb] = sides(pairs[q]);
      ++count[pa];
      if (pb != pa) ++count[pb];
    }
  }
  std::int64_t at = 0;
  for (int k = 0; k < parts; ++k) {
    begin[k] = at;
    for (int r = 0; r < R; ++r) {
      std::int64_t& slot = fill[static_cast<std::size_t>(r) * parts + k];
      const std::int64_t n = slot;
      slot = at;
      at += n;
    }
  }
  begin[parts] = at;
  item.resize(static_cast<std::size_t>(at));
#pragma omp parallel for schedule(static, 1)
  for (int r = 0; r < R; ++r) {
    std::int64_t* next = &fill[static_cast<std::size_t>(r) * parts];
    const auto [b, e] = range(r);
    for (std::size_t q = b; q < e; ++q) {
      const auto [pa, pb] = sides(pairs[q]);
      const std::uint64_t code = static_cast<std::uint64_t>(q) << 2;
      if (pa == pb) {
        item[next[pa]++] = code | 3;
      } else {
        item[next[pa]++] = code | 1;
        item[next[pb]++] = code | 2;
      }
    }
  }
}

namespace {

const ContactPartition& partitionOf(const ContactList& con, const CellSet& cells,
                                    ContactPartition& scratch) {
  const int parts = contactParts(con.pairs.size());
  if (con.partition.num_pairs == con.pairs.size() && con.partition.parts == parts)
    return con.partition;
  scratch.build(con.pairs, cells.tri_cell, cells.numCells(), parts);
  return scratch;
}

// The consistent stiffness (ks > 0) reads each pair's moments, which only a detection whose law
// asked for them has.
void checkMoments(const ContactList& con, double ks) {
  if (ks > 0 && con.moments.size() != con.pairs.size())
    throw std::logic_error(
        "contact friction: the consistent stiffness needs the contacts' moments "
        "(ContactLaw::stiffness_moments)");
}

// f(q, owns_a, owns_b) for every pair q and the sides a part owns, each part's pairs in pair
// order; the parts run concurrently and write disjoint vertices.
template <class F>
void forEachOwnedSide(const ContactPartition& part, const F& f) {
  if (part.parts <= 1) {
    for (std::size_t q = 0; q < part.num_pairs; ++q) f(q, true, true);
    return;
  }
#pragma omp parallel for schedule(static, 1)
  for (int k = 0; k < part.parts; ++k)
    for (std::int64_t e = part.begin[k]; e < part.begin[k + 1]; ++e) {
      const std::uint64_t code = part.item[e];
      f(static_cast<std::size_t>(code >> 2), (code & 1) != 0, (code & 2) != 0);
    }
}

}  // namespace

void detectContacts(const CellSet& cells, const Geometry& geo, const ContactLaw& law,
                    ContactQuadrature quadrature, ContactList& out, CandidateCache* cache) {
  const int nt = cells.numTriangles();
  out.partition.num_pairs = 0;
  out.partition.parts = 0;
  out.tri_contact_area.assign(nt, 0.0);
  out.tri_contact_fraction.assign(nt, 0.0);
  out.vertex_contact_area.assign(cells.numVertices(), 0.0);
  out.cell_contact_area.assign(cells.numCells(), 0.0);
  if (cells.numCells() < 2) {
    out.pairs.clear();
    out.moments.clear();
    return;
  }
  const auto candidates = cache ? cache->find(cells, law.h0)
                                : findContactCandidates(cells.x, cells.tri, cells.tri_cell, law.h0);
  auto corners = [&](int t) {
    const Tri& f = cells.tri[t];
    return std::array<Vec3, 3>{cells.x.col(f[0]), cells.x.col(f[1]), cells.x.col(f[2])};
  };
  auto& frame = out.tri_frames;
  frame.resize(nt);
#pragma omp parallel for schedule(static) if (nt > grain().min_items)
  for (int t = 0; t < nt; ++t) frame[t] = triangleFrame(corners(t));
  // Narrow phase: the active pairs in candidate order — the same list for any thread count.
  const auto nc = static_cast<std::int64_t>(candidates.size());
  // keep(pair, moments) for each active candidate of [begin, end), in order.
  auto narrow = [&](std::int64_t begin, std::int64_t end, auto&& keep) {
    ContactMoments m;
    for (std::int64_t i = begin; i < end; ++i) {
      const auto [ta, tb] = candidates[i];
      const TriangleContact c =
          computeTriangleContact(corners(ta), corners(tb), frame[ta], frame[tb], law, quadrature,
                                 law.stiffness_moments ? &m : nullptr, ContactOutputs::PairOnly);
      if (c.active) keep(ContactPair{ta, tb, c}, m);
    }
  };
  if (!law.stiffness_moments) out.moments.clear();
  const int R = nc > grain().min_items ? threads() : 1;
  if (R == 1) {
    out.pairs.clear();
    out.moments.clear();
    narrow(0, nc, [&](const ContactPair& p, const ContactMoments& m) {
      out.pairs.push_back(p);
      if (law.stiffness_moments) out.moments.push_back(m);
    });
  } else {
    // One range of candidates per thread, the first written straight into the list over the last
    // detection's pairs (which are not cleared: growing the list again would zero its new
    // elements first), the others into kept buffers, then copied after the first range's pairs
    // by all threads together. (On two threads of the 2 × 100 fusion the join took 2.4 ms of
    // each detection when one thread zeroed and copied the second range's pairs.)
    // (The 64-candidate chunks on a dynamic schedule this replaces balanced no better on the
    // 2 × 100 fusion — its contacts phase on two threads is as fast — and their join copied
    // every pair once more.)
    auto& found = out.narrow_buffers;
    if (found.size() < static_cast<std::size_t>(R)) found.resize(static_cast<std::size_t>(R));
    const auto range = [&](int r) { return nc * r / R; };
    std::size_t first = 0;  // pairs of the first range
#pragma omp parallel for schedule(static, 1) num_threads(R)
    for (int r = 0; r < R; ++r) {
      if (r == 0) {
        narrow(range(0), range(1), [&](const ContactPair& p, const ContactMoments& m) {
          if (first < out.pairs.size())
            out.pairs[first] = p;
          else
            out.pairs.push_back(p);
          if (law.stiffness_moments) {
            if (first < out.moments.size())
              out.moments[first] = m;
            else
              out.moments.push_back(m);
          }
          ++first;
        });
        continue;
      }
      ContactList::NarrowBuffer& buf = found[r];
      buf.pairs.clear();
      buf.moments.clear();
      narrow(range(r), range(r + 1), [&](const ContactPair& p, const ContactMoments& m) {
        buf.pairs.push_back(p);
        if (law.stiffness_moments) buf.moments.push_back(m);
      });
    }
    std::vector<std::size_t> at(static_cast<std::size_t>(R) + 1, 0);
    at[1] = first;
    for (int r = 1; r < R; ++r) at[r + 1] = at[r] + found[r].pairs.size();
    out.pairs.resize(at[R]);
    out.moments.resize(law.stiffness_moments ? at[R] : 0);
    // Each thread copies an equal share of [at[1], at[R]), whichever buffers it falls in.
    const std::size_t copied = at[R] - at[1];
#pragma omp parallel for schedule(static, 1) num_threads(R)
    for (int j = 0; j < R; ++j) {
      const std::size_t lo = at[1] + copied * j / R, hi = at[1] + copied * (j + 1) / R;
      for (int r = 1; r < R; ++r) {
        const std::size_t b = std::max(lo, at[r]), e = std::min(hi, at[r + 1]);
        if (b >= e) continue;
        std::copy(found[r].pairs.begin() + (b - at[r]), found[r].pairs.begin() + (e - at[r]),
                  out.pairs.begin() + b);
        if (law.stiffness_moments)
          std::copy(found[r].moments.begin() + (b - at[r]), found[r].moments.begin() + (e - at[r]),
                    out.moments.begin() + b);
      }
    }
  }
  const std::size_t total = out.pairs.size();
  out.partition.build(out.pairs, cells.tri_cell, cells.numCells(), contactParts(total));
  // Each triangle's area sum in pair order, by the part that owns its cell (the same bits as one
  // pass over the pairs).
  forEachOwnedSide(out.partition, [&](std::size_t q, bool own_a, bool own_b) {
    const ContactPair& p = out.pairs[q];
    if (own_a) out.tri_contact_area[p.ta] += p.c.area;
    if (own_b) out.tri_contact_area[p.tb] += p.c.area;
  });
  // Per cell: a cell's triangles touch only its own vertices, in the order of one pass.
#pragma omp parallel for schedule(static) if (nt > grain().min_items)
  for (int c = 0; c < cells.numCells(); ++c)
    for (int t = cells.cell_tri_begin[c]; t < cells.cell_tri_begin[c + 1]; ++t) {
      if (out.tri_contact_area[t] <= 0) continue;
      const double f = std::min(1.0, out.tri_contact_area[t] / geo.tri_area[t]);
      out.tri_contact_fraction[t] = f;
      const double a = f * geo.tri_area[t];
      for (int k = 0; k < 3; ++k) out.vertex_contact_area[cells.tri[t][k]] += a / 3.0;
      out.cell_contact_area[c] += a;
    }
}

double ContactAdhesion::addForces(const StepContext& ctx, Eigen::Matrix3Xd& f) const {
  if (!ctx.contacts) return 0;
  const ContactList& con = *ctx.contacts;
  ContactPartition scratch;
  forEachOwnedSide(partitionOf(con, ctx.cells, scratch),
                   [&](std::size_t q, bool own_a, bool own_b) {
                     const ContactPair& p = con.pairs[q];
                     const Tri& a = ctx.cells.tri[p.ta];
                     const Tri& b = ctx.cells.tri[p.tb];
                     if (own_a)
                       for (int k = 0; k < 3; ++k)
                         f.col(a[k]) += p.c.force_weight_a[k] * p.c.normal;
                     if (own_b)
                       for (int k = 0; k < 3; ++k)
                         f.col(b[k]) -= p.c.force_weight_b[k] * p.c.normal;
                   });
  double energy = 0;
  for (const ContactPair& p : con.pairs) energy += p.c.energy;
  return energy;
}

ContactFriction ContactFriction::part(Part which) const {
  switch (which) {
    case Part::Tangential:
      return {0.0, xi_t_, 0.0};
    case Part::Normal:
      return {xi_n_, 0.0, 0.0};
    case Part::Springs:
      break;
  }
  return {0.0, 0.0, k_};
}

Eigen::Matrix3d ContactFriction::pairMatrix(const ContactPair& p, double stiffness_dt) const {
  const Vec3& n = p.c.normal;
  const Eigen::Matrix3d nn = n * n.transpose();
  return p.c.area * ((xi_n_ + stiffness_dt * k_) * nn + xi_t_ * (Eigen::Matrix3d::Identity() - nn));
}

namespace {

// The contact pairs' couplings of one step: −w_ik G across each pair (G = area (ξ_t I + d n̂n̂ᵀ),
// w_ik = λ_i^A λ_k^B), and for the consistent stiffness (ros2) its off-diagonal blocks.
class PairCoupling : public Coupling {
 public:
  // One contact pair as the product needs it: vertices, barycentric weights, area and normal.
  // 104 bytes: the product streams them every CG iteration.
  struct PairOp {
    PairOp() {}  // left uninitialised: every one is written before use, and resize must not zero
                 // the list's ~13 MB every step
    int a[3], b[3];
    double wa[3], wb[3];
    double area;
    double n[3];
  };
  // The consistent stiffness' moments per pair (ros2 only): m_ab (9), then the off-diagonal
  // m_aa (01, 02, 12) and m_bb (01, 02, 12). Copied from the contacts so that a product streams
  // 104 bytes per pair, not the whole TriangleContact (reading those doubled the time per CG
  // iteration), and kept apart so that contact-implicit's pair ops stay as small as they were.
  using Moments = std::array<double, 15>;

  void addProduct(const double* v, double* y) const override {
    // The off-diagonal blocks −w_ik G: vertex i of A gets −λ_i^A G u_B with u_B = Σ_k λ_k^B v_k.
    if (ops.empty()) return;
    // One loop per kind, so that contact-implicit's pairs run without the consistent stiffness'
    // branches (a runtime test cost ~20 % of the product).
    if (ks > 0)
      product<true>(v, y);
    else
      product<false>(v, y);
  }

  // What a pair adds, computed for two pairs at once in the two lanes of an SSE2 register (the
  // product was scalar arithmetic, bound by instructions rather than memory: perf).
  // Each lane runs pairValues' operations in the scalar order, and IEEE arithmetic is exact per
  // lane, so the values are the scalar ones bit for bit; they are added to y pair by pair in the
  // pair order, as before.
  using Lanes = double __attribute__((vector_size(16)));

  // A pair's (or two pairs') values: G u_A and G u_B (what B's and A's vertices get), and the
  // consistent stiffness' normal forces on A's and B's vertices (its off-diagonal part).
  template <class T>
  struct PairValues {
    T ga[3], gb[3], fa[3], fb[3];
  };
  template <bool consistent, class T>
  static void pairValues(const T (&wa)[3], const T (&wb)[3], const T (&n)[3], const T& s,
                         const T& d, const T (&va)[3][3], const T (&vb)[3][3], const T* m,
                         const T& ks, PairValues<T>& out) {
    const T zero{};
    T ua[3] = {zero, zero, zero}, ub[3] = {zero, zero, zero};
    for (int i = 0; i < 3; ++i)
      for (int c = 0; c < 3; ++c) {
        ua[c] += wa[i] * va[i][c];
        ub[c] += wb[i] * vb[i][c];
      }
    const T na = n[0] * ua[0] + n[1] * ua[1] + n[2] * ua[2];
    const T nb = n[0] * ub[0] + n[1] * ub[1] + n[2] * ub[2];
    // G = s I + d n̂n̂ᵀ: s and d as addFriction's diagonal G has them, the same bits.
    for (int c = 0; c < 3; ++c) {
      out.gb[c] = s * ub[c] + d * nb * n[c];
      out.ga[c] = s * ua[c] + d * na * n[c];
    }
    if constexpr (consistent) {
      // Normal components of the vertices' velocities, then the off-diagonal part of
      // K = k [M_aa, −M_ab; −M_abᵀ, M_bb] ⊗ n̂n̂ᵀ (the diagonal sits in Γ).
      T an[3], bn[3];
      for (int i = 0; i < 3; ++i) {
        an[i] = bn[i] = zero;
        for (int c = 0; c < 3; ++c) {
          an[i] += n[c] * va[i][c];
          bn[i] += n[c] * vb[i][c];
        }
      }
      // Off-diagonal index of (i, j), i ≠ j, in the symmetric triples: 01 → 0, 02 → 1, 12 → 2.
      auto off = [](int i, int j) { return i + j - 1; };
      for (int i = 0; i < 3; ++i) {
        T sa = zero, sb = zero;
        for (int j = 0; j < 3; ++j) {
          if (j != i) {
            sa += m[9 + off(i, j)] * an[j];
            sb += m[12 + off(i, j)] * bn[j];
          }
          sa -= m[3 * i + j] * bn[j];
          sb -= m[3 * j + i] * an[j];
        }
        out.fa[i] = ks * sa;
        out.fb[i] = ks * sb;
      }
    }
  }

  template <bool consistent>
  void scatter(const PairOp& op, bool own_a, bool own_b, const double* ga, const double* gb,
               const double* fa, const double* fb, double* y) const {
    auto side = [&](const int* t, const double* w, const double* g, const double* fn) {
      for (int i = 0; i < 3; ++i) {
        double* yv = y + 3 * static_cast<std::int64_t>(t[i]);
        for (int c = 0; c < 3; ++c) yv[c] -= w[i] * g[c];
        if constexpr (consistent)
          for (int c = 0; c < 3; ++c) yv[c] += fn[i] * op.n[c];
      }
    };
    if (own_a) side(op.a, op.wa, gb, fa);
    if (own_b) side(op.b, op.wb, ga, fb);
  }

  template <bool consistent>
  void one(std::size_t q, bool own_a, bool own_b, const double* v, double* y) const {
    const PairOp& op = ops[q];
    double va[3][3], vb[3][3];
    for (int i = 0; i < 3; ++i)
      for (int c = 0; c < 3; ++c) {
        va[i][c] = v[3 * op.a[i] + c];
        vb[i][c] = v[3 * op.b[i] + c];
      }
    PairValues<double> r;
    pairValues<consistent>(op.wa, op.wb, op.n, op.area * xi_t, op.area * d_factor, va, vb,
                           consistent ? moments[q].data() : nullptr, ks, r);
    scatter<consistent>(op, own_a, own_b, r.ga, r.gb, r.fa, r.fb, y);
  }

  template <bool consistent>
  void two(std::size_t q0, bool own_a0, bool own_b0, std::size_t q1, bool own_a1, bool own_b1,
           const double* v, double* y) const {
    const PairOp& p = ops[q0];
    const PairOp& o = ops[q1];
    Lanes wa[3], wb[3], n[3], va[3][3], vb[3][3];
    for (int i = 0; i < 3; ++i) {
      wa[i] = Lanes{p.wa[i], o.wa[i]};
      wb[i] = Lanes{p.wb[i], o.wb[i]};
      n[i] = Lanes{p.n[i], o.n[i]};
      for (int c = 0; c < 3; ++c) {
        va[i][c] = Lanes{v[3 * p.a[i] + c], v[3 * o.a[i] + c]};
        vb[i][c] = Lanes{v[3 * p.b[i] + c], v[3 * o.b[i] + c]};
      }
    }
    const Lanes s{p.area * xi_t, o.area * xi_t}, d{p.area * d_factor, o.area * d_factor};
    const Lanes kv{ks, ks};
    Lanes m[15];
    if constexpr (consistent)
      for (int k = 0; k < 15; ++k) m[k] = Lanes{moments[q0][k], moments[q1][k]};
    PairValues<Lanes> r;
    pairValues<consistent>(wa, wb, n, s, d, va, vb, m, kv, r);
    double out[2][4][3];
    for (int c = 0; c < 3; ++c)
      for (int l = 0; l < 2; ++l) {
        out[l][0][c] = r.ga[c][l];
        out[l][1][c] = r.gb[c][l];
        out[l][2][c] = consistent ? r.fa[c][l] : 0.0;
        out[l][3][c] = consistent ? r.fb[c][l] : 0.0;
      }
    scatter<consistent>(p, own_a0, own_b0, out[0][0], out[0][1], out[0][2], out[0][3], y);
    scatter<consistent>(o, own_a1, own_b1, out[1][0], out[1][1], out[1][2], out[1][3], y);
  }

  // As forEachOwnedSide, two items at a time (the last alone): each part's pairs in pair order.
  template <bool consistent>
  void product(const double* v, double* y) const {
    if (part->parts <= 1) {
      const std::size_t n = part->num_pairs;
      std::size_t q = 0;
      for (; q + 1 < n; q += 2) two<consistent>(q, true, true, q + 1, true, true, v, y);
      if (q < n) one<consistent>(q, true, true, v, y);
      return;
    }
#pragma omp parallel for schedule(static, 1)
    for (int k = 0; k < part->parts; ++k) {
      const std::int64_t end = part->begin[k + 1];
      std::int64_t e = part->begin[k];
      auto q = [&](std::int64_t i) { return static_cast<std::size_t>(part->item[i] >> 2); };
      auto own_a = [&](std::int64_t i) { return (part->item[i] & 1) != 0; };
      auto own_b = [&](std::int64_t i) { return (part->item[i] & 2) != 0; };
      for (; e + 1 < end; e += 2)
        two<consistent>(q(e), own_a(e), own_b(e), q(e + 1), own_a(e + 1), own_b(e + 1), v, y);
      if (e < end) one<consistent>(q(e), own_a(e), own_b(e), v, y);
    }
  }
  void forEachBlock(const BlockSink& sink) const override {
    // The off-diagonal blocks that addProduct applies: −w_ik G across the pair, and for
    // the consistent stiffness −k m_ab n̂n̂ᵀ across, +k m_aa n̂n̂ᵀ within each triangle.
    const bool consistent = !ops.empty() && ks > 0;
    for (std::size_t q = 0; q < ops.size(); ++q) {
      const PairOp& op = ops[q];
      const Vec3 n(op.n[0], op.n[1], op.n[2]);
      const Eigen::Matrix3d nn = n * n.transpose();
      const Eigen::Matrix3d g =
          (op.area * xi_t) * Eigen::Matrix3d::Identity() + (op.area * d_factor) * nn;
      for (int i = 0; i < 3; ++i)
        for (int k = 0; k < 3; ++k) {
          Eigen::Matrix3d m = -(op.wa[i] * op.wb[k]) * g;
          if (consistent) m -= (ks * moments[q][3 * i + k]) * nn;
          sink(op.a[i], op.b[k], m);
        }
      if (!consistent) continue;
      const Moments& mo = moments[q];
      for (int i = 0; i < 3; ++i)
        for (int j = i + 1; j < 3; ++j) {
          sink(op.a[i], op.a[j], (ks * mo[9 + i + j - 1]) * nn);
          sink(op.b[i], op.b[j], (ks * mo[12 + i + j - 1]) * nn);
        }
    }
  }

  std::vector<PairOp> ops;
  std::vector<Moments> moments;
  double xi_t = 0;
  double d_factor = 0;         // ξ_n + Δt k − ξ_t (contact-implicit), ξ_n − ξ_t
  double ks = 0;               // factor of the consistent stiffness (0 unless used)
  ContactPartition partition;  // when the contact list came without one
  const ContactPartition* part = nullptr;
};

}  // namespace

void ContactFriction::addFriction(const StepContext& ctx, FrictionOperator& op) const {
  if (!ctx.contacts) return;
  auto& coupling = op.coupling<PairCoupling>(this);
  BlockMatrix& gamma = op.diagonal();
  // The centroid spring goes with the friction blocks; the consistent one separately.
  const double spring_dt = ctx.consistent_stiffness ? 0.0 : ctx.contact_stiffness_dt;
  const double ks = ctx.consistent_stiffness ? ctx.contact_stiffness_dt * k_ : 0.0;
  const ContactList& con = *ctx.contacts;
  checkMoments(con, ks);
  coupling.part = &partitionOf(con, ctx.cells, coupling.partition);
  coupling.ops.resize(con.pairs.size());
  coupling.moments.resize(ks > 0 ? con.pairs.size() : 0);
  coupling.ks = ks;
  coupling.xi_t = xi_t_;
  coupling.d_factor = xi_n_ + spring_dt * k_ - xi_t_;
  // The product's copy of a pair, made in the one visit that owns its A side (one pass over the
  // pairs instead of two: each pair is 152 bytes, and ~130 000 of them outgrow the caches).
  auto makeOp = [&](std::size_t q) {
    const ContactPair& p = con.pairs[q];
    const Tri& a = ctx.cells.tri[p.ta];
    const Tri& b = ctx.cells.tri[p.tb];
    PairCoupling::PairOp& pop = coupling.ops[q];
    for (int i = 0; i < 3; ++i) {
      pop.a[i] = a[i];
      pop.b[i] = b[i];
      pop.wa[i] = p.c.bary_a[i];
      pop.wb[i] = p.c.bary_b[i];
    }
    pop.area = p.c.area;
    if (ks > 0) {
      PairCoupling::Moments& m = coupling.moments[q];
      const ContactMoments& mo = con.moments[q];
      for (int k = 0; k < 9; ++k) m[k] = mo.ab[k];
      m[9] = mo.aa[1], m[10] = mo.aa[2], m[11] = mo.aa[5];
      m[12] = mo.bb[1], m[13] = mo.bb[2], m[14] = mo.bb[5];
    }
    for (int k = 0; k < 3; ++k) pop.n[k] = p.c.normal[k];
  };
  // Σ_k w_ik G = λ_i^A (Σ_k λ_k^B) G on vertex i of A, and the same for B.
  forEachOwnedSide(*coupling.part, [&](std::size_t q, bool own_a, bool own_b) {
    if (own_a) makeOp(q);
    const ContactPair& p = con.pairs[q];
    const Eigen::Matrix3d g = pairMatrix(p, spring_dt);
    const Eigen::Matrix3d nn = p.c.normal * p.c.normal.transpose();
    // m_own: ∫ λλ dS of the side's own triangle (the consistent stiffness' diagonal), if used.
    auto side = [&](const Tri& t, const std::array<double, 3>& w, const std::array<double, 3>& wo,
                    const double* m_own) {
      const double so = wo[0] + wo[1] + wo[2];
      for (int k = 0; k < 3; ++k) {
        if (ks > 0) gamma.addDiagonal(t[k], (ks * m_own[4 * k]) * nn);
        if (w[k] > 0) gamma.addDiagonal(t[k], (w[k] * so) * g);
      }
    };
    const ContactMoments* mo = ks > 0 ? &con.moments[q] : nullptr;
    if (own_a) side(ctx.cells.tri[p.ta], p.c.bary_a, p.c.bary_b, mo ? mo->aa.data() : nullptr);
    if (own_b) side(ctx.cells.tri[p.tb], p.c.bary_b, p.c.bary_a, mo ? mo->bb.data() : nullptr);
  });
}

}  // namespace activefoam
