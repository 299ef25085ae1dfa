#include "vmf_fit.h"

#include <ceres/ceres.h>

#include <algorithm>
#include <cmath>
#include <memory>

#include "cell_probability.h"
#include "exp_in_place.h"
#include "stf/hemisphere.h"
#include "stf/tilt.h"

namespace stf::fit {

namespace {

// Spherical k-means and EM start lobes no narrower than this; the likelihood stage may narrow
// them further, up to VmfFitOptions::max_kappa (1e8). A lobe already inside one cell barely
// changes the binned likelihood as it narrows, so near-delta lobes tend to end near 1e7.
constexpr double kMaxStartKappa = 1e7;
constexpr double kMaxLogit = 40;  // lobe weights below e^-40 of the heaviest are zero to a double

Vec3 cell_centre(const CellQuadrature& q, std::size_t c) {
  Vec3 s{0, 0, 0};
  for (int j = 0; j < q.per_cell; ++j) {
    const Vec3& p = q.point[c * q.per_cell + j];
    double w = q.weight[c * q.per_cell + j];
    s = {s.x + w * p.x, s.y + w * p.y, s.z + w * p.z};
  }
  return normalize(s);
}

// d log(norm(kappa)) / d kappa for norm = kappa / (2 pi (1 - e^{-2 kappa})):
// 1/kappa - 2 / expm1(2 kappa), whose two terms cancel as kappa -> 0; there the series.
double dlog_norm(double kappa) {
  if (kappa < 1e-3) return 1 - kappa / 3;
  return 1 / kappa - 2 / std::expm1(2 * kappa);
}

// The vMF normalisation kappa / (2 pi (1 - e^{-2 kappa})) and d log(norm) / d kappa with one
// exponential (none above kappa = 20, where e^{-2 kappa} < 1e-17).
void widened_norm(double kappa, double& norm, double& dlog) {
  if (kappa < 1e-3) {
    norm = vmf_pdf(kappa, 1.0);
    dlog = dlog_norm(kappa);
    return;
  }
  double e = kappa > 20 ? 0.0 : std::exp(-2 * kappa);
  norm = kappa / (2 * kPi * (1 - e));
  dlog = 1 / kappa - 2 * e / (1 - e);
}

// Signed deviance residual of count n against expectation mu, and d residual / d mu:
// sum r^2 is the Poisson deviance, so least squares on r is maximum likelihood.
void deviance_residual(double n, double mu, double& r, double& dr) {
  mu = std::max(mu, 1e-300);
  if (n <= 0) {
    r = -std::sqrt(2 * mu);
    dr = -1 / std::sqrt(2 * mu);
    return;
  }
  double d = 2 * (n * std::log(n / mu) - (n - mu));
  if (d < 1e-12 * n) {  // mu ~ n: r ~ (n - mu) / sqrt(n)
    r = (n - mu) / std::sqrt(n);
    dr = -1 / std::sqrt(n);
    return;
  }
  double root = std::sqrt(d);
  r = n > mu ? root : -root;
  dr = -std::abs(mu - n) / (mu * root);
}

// Residuals: one per cell with counts, and one for all empty cells together (their deviance
// is 2 sum mu = 2 N (1 - sum of the other cells' probabilities)). Parameter blocks: softmax
// logits [K], log kappa [K], then the K mean directions [3] each (on SphereManifold<3>).
// Each lobe is integrated over the cells at the coarsest quadrature level accurate for its
// own kappa (QuadratureLevels::for_kappa): broad lobes at the cell centres, narrow ones on
// sub-cells, so a mixture costs what its narrowest lobe needs only once.
class PoissonDeviance final : public ceres::CostFunction {
 public:
  PoissonDeviance(const QuadratureLevels& levels, const std::vector<double>& counts, int lobes,
                  const OutwardFactors* outward, double min_kappa, double max_kappa, const BinTurn* turn = nullptr)
      : levels_(levels), outward_(outward), lobes_(lobes), row_of_cell_(counts.size(), -1),
        min_log_kappa_(std::log(min_kappa)), max_log_kappa_(std::log(max_kappa)) {
    if (turn && turn->rate != 0) turn_nodes(*turn);
    for (int level = 0; level <= QuadratureLevels::kMaxLevel; ++level)
      for (double a : levels.at(level).weight) max_sub_cell_[level] = std::max(max_sub_cell_[level], a);
    for (double n : counts) widen_above_ += n;
    widen_above_ = 0.6 / std::sqrt(std::max(widen_above_, 1.0));
    for (std::size_t c = 0; c < counts.size(); ++c) {
      total_ += counts[c];
      if (counts[c] > 0) {
        row_of_cell_[c] = int(count_.size());
        count_.push_back(counts[c]);
      }
    }
    set_num_residuals(int(count_.size()) + 1);
    mutable_parameter_block_sizes()->push_back(lobes);
    mutable_parameter_block_sizes()->push_back(lobes);
    for (int k = 0; k < lobes; ++k) mutable_parameter_block_sizes()->push_back(3);
  }

  bool Evaluate(double const* const* params, double* residuals, double** jacobians) const override {
    const int K = lobes_, rows = int(count_.size());
    // Log kappa and the logits are used clamped to their bounds, with no derivative beyond
    // them: a parameter that runs past a bound stays there without holding the others back.
    // (Bounds declared to Ceres would add a projected line search, with two or three more
    // Jacobians, to every iteration.)
    std::vector<double> logit(K), log_kappa(K), w(K);
    std::vector<char> free_logit(K), free_kappa(K);
    for (int k = 0; k < K; ++k) {
      logit[k] = std::clamp(params[0][k], -kMaxLogit, kMaxLogit), free_logit[k] = logit[k] == params[0][k];
      log_kappa[k] = std::clamp(params[1][k], min_log_kappa_, max_log_kappa_), free_kappa[k] = log_kappa[k] == params[1][k];
    }
    double max_logit = *std::max_element(logit.begin(), logit.end()), sum = 0;
    for (int k = 0; k < K; ++k) sum += (w[k] = std::exp(logit[k] - max_logit));
    for (double& v : w) v /= sum;

    // Per lobe: cell masses on the rows and totals over the sphere, with derivatives by
    // log kappa and by the mean. Levenberg-Marquardt asks for the residuals alone at every trial
    // step (about half the calls): the derivatives are then not accumulated.
    const bool derivatives = jacobians != nullptr;
    std::vector<double> mass(std::size_t(K) * rows, 0), d_theta(derivatives ? mass.size() : 0, 0),
        d_mean(derivatives ? 3 * mass.size() : 0, 0);
    std::vector<double> total(K, 0), total_theta(K, 0), total_mean(3 * K, 0);
    CopyScratch scratch(rows, derivatives, !nodes_.empty());
    for (int k = 0; k < K; ++k) {
      const double kappa = std::exp(log_kappa[k]);
      const Vec3 mean = normalize({params[2 + k][0], params[2 + k][1], params[2 + k][2]});
      const std::size_t at = std::size_t(k) * rows;
      integrate_bin_lobe(mean, kappa,
                         {&mass[at], derivatives ? &d_theta[at] : nullptr, derivatives ? &d_mean[3 * at] : nullptr,
                          &total[k], &total_theta[k], &total_mean[3 * k]},
                         scratch);
    }

    // A hemispherical lobe turned wholly below the bin's tangent planes has no mass at all: it
    // then adds nothing and has no gradient (its masses and their derivatives are all 0, so a
    // total of 1 keeps 0 / 0 out).
    for (double& t : total)
      if (!(t > 1e-150)) t = 1;

    std::vector<double> share(K);  // p_row = sum_k share_k mass_k,row
    for (int k = 0; k < K; ++k) share[k] = w[k] / total[k];

    // Probabilities, residuals, d residual / d mu.
    std::vector<double> p(rows, 0), dr(rows + 1);
    double p_rest = 1;
    for (int row = 0; row < rows; ++row) {
      for (int k = 0; k < K; ++k) p[row] += share[k] * mass[std::size_t(k) * rows + row];
      p_rest -= p[row];
      deviance_residual(count_[row], total_ * p[row], residuals[row], dr[row]);
    }
    deviance_residual(0, total_ * std::max(p_rest, 0.0), residuals[rows], dr[rows]);
    if (!jacobians) return true;

    // d p_row / d parameter, then the chain rule; the empty-cells residual moves opposite to
    // the sum of the others.
    auto fill = [&](int block, int width, auto dp) {
      if (!jacobians[block]) return;
      double* J = jacobians[block];
      std::vector<double> rest(width, 0);
      for (int row = 0; row < rows; ++row) {
        for (int col = 0; col < width; ++col) {
          double d = dp(row, col);
          J[row * width + col] = dr[row] * total_ * d;
          rest[col] -= d;
        }
      }
      for (int col = 0; col < width; ++col) J[rows * width + col] = p_rest > 0 ? dr[rows] * total_ * rest[col] : 0;
    };
    // Per lobe, p_row = w_k mass_row / total: its derivatives are (w_k / total) d mass_row -
    // (w_k d total / total^2) mass_row, with the quotients taken once per lobe.
    std::vector<double> theta_pull(K), mean_pull(3 * std::size_t(K));
    for (int k = 0; k < K; ++k) {
      theta_pull[k] = share[k] * total_theta[k] / total[k];
      for (int axis = 0; axis < 3; ++axis) mean_pull[3 * k + axis] = share[k] * total_mean[3 * k + axis] / total[k];
    }
    fill(0, K, [&](int row, int j) {
      return free_logit[j] ? share[j] * mass[std::size_t(j) * rows + row] - w[j] * p[row] : 0.0;
    });
    fill(1, K, [&](int row, int k) {
      std::size_t r = std::size_t(k) * rows + row;
      return free_kappa[k] ? share[k] * d_theta[r] - theta_pull[k] * mass[r] : 0.0;
    });
    for (int k = 0; k < K; ++k) {
      fill(2 + k, 3, [&](int row, int axis) {
        std::size_t r = std::size_t(k) * rows + row;
        return share[k] * d_mean[3 * r + axis] - mean_pull[3 * k + axis] * mass[r];
      });
    }
    return true;
  }

  // The probabilities of the rows' cells under `lobes` (the deviance's model, without the
  // residuals), each lobe integrated as for `escapes` escapes.
  std::vector<double> probabilities(const std::vector<VmfLobe>& lobes, double escapes) {
    total_ = escapes;
    widen_above_ = 0.6 / std::sqrt(std::max(escapes, 1.0));
    const int rows = int(count_.size());
    std::vector<double> p(std::size_t(rows), 0.0), mass(p.size());
    CopyScratch scratch(rows, false, !nodes_.empty());
    for (const VmfLobe& l : lobes) {
      if (l.weight <= 0) continue;
      std::fill(mass.begin(), mass.end(), 0.0);
      double total = 0, unused[4] = {0, 0, 0, 0};
      integrate_bin_lobe(l.mean, l.kappa, {mass.data(), nullptr, nullptr, &total, unused, unused + 1}, scratch);
      if (!(total > 1e-150)) continue;
      for (int r = 0; r < rows; ++r) p[std::size_t(r)] += l.weight * mass[std::size_t(r)] / total;
    }
    std::vector<double> cells(row_of_cell_.size(), 0.0);
    for (std::size_t c = 0; c < cells.size(); ++c)
      if (row_of_cell_[c] >= 0) cells[c] = p[std::size_t(row_of_cell_[c])];
    return cells;
  }

  // Where one lobe's integrals go: its masses on the rows (and, with derivatives, their
  // derivatives by log kappa and by the mean), and its totals over the sphere.
  struct LobeIntegrals {
    double *mass, *d_theta, *d_mean;
    double *total, *total_theta, *total_mean;
    // When given, the rows the lobe reaches are listed once each (`marked` flags them).
    std::vector<int>* touched = nullptr;
    char* marked = nullptr;
  };

  // The outward factor at quadrature point i (at x): from a bin's table, from a turned bin's
  // edges, or 1 for plain lobes.
  struct PointFactor {
    const OutwardFactors* table = nullptr;
    const OutwardBin* turned = nullptr;
    const double* at_level = nullptr;
    void for_level(int level) { at_level = table ? (*table)[std::size_t(level)].data() : nullptr; }
    double operator()(std::size_t i, const Vec3& x) const { return at_level ? at_level[i] : turned ? (*turned)(x) : 1.0; }
  };

  // Points of one lobe whose exponentials are taken together (exp_in_place, several to an
  // instruction): each point's exponent and what multiplies the exponential, in the order the
  // points were met, so that each row's sums are added in the same order as point by point.
  struct PointBatch {
    static constexpr int kSize = 64;
    int n = 0;
    double exponent[kSize], scale[kSize], theta[kSize], theta_scale[kSize], mean_scale[kSize], factor[kSize];
    int row[kSize];
    const Vec3* x[kSize];
  };

  // Adds the batch's points to `out` and empties it. The totals are summed here first: added to
  // `out` point by point they would be a chain of stores the compiler cannot keep in registers
  // (`out`'s arrays might overlap them).
  static void flush(PointBatch& b, bool derivatives, const LobeIntegrals& out) {
    exp_in_place(b.exponent, b.n);
    double total = 0, total_theta = 0, total_mean[3] = {0, 0, 0};
    for (int k = 0; k < b.n; ++k) {
      const int row = b.row[k];
      const double f = b.factor[k];
      double v = b.scale[k] * b.exponent[k];
      double vt = v * b.theta[k] * b.theta_scale[k];  // d v / d log kappa
      double vm = v * b.mean_scale[k];                // d v / d mean = vm * x
      v *= f;  // the outward factor of hemispherical lobes
      total += v;
      if (row >= 0) out.mass[row] += v;
      if (row >= 0 && out.touched && !out.marked[row]) out.marked[row] = 1, out.touched->push_back(row);
      if (!derivatives) continue;
      const Vec3& x = *b.x[k];
      vt *= f, vm *= f;
      total_theta += vt;
      total_mean[0] += vm * x.x, total_mean[1] += vm * x.y, total_mean[2] += vm * x.z;
      if (row < 0) continue;
      out.d_theta[row] += vt;
      out.d_mean[3 * row] += vm * x.x, out.d_mean[3 * row + 1] += vm * x.y, out.d_mean[3 * row + 2] += vm * x.z;
    }
    *out.total += total;
    if (derivatives) {
      *out.total_theta += total_theta;
      for (int axis = 0; axis < 3; ++axis) out.total_mean[axis] += total_mean[axis];
    }
    b.n = 0;
  }

  // Adds one lobe's cell masses, totals and their derivatives to `out`, each point times its
  // outward factor.
  void integrate_lobe(const Vec3& mean, double kappa, PointFactor factor, const LobeIntegrals& out) const {
    const bool derivatives = out.d_theta != nullptr;
    const int level = levels_.level_for_kappa(kappa, total_);
    const CellQuadrature& q = levels_.at(level);
    factor.for_level(level);
    const double max_sub_cell = max_sub_cell_[level];
    // The widening is the quadrature's second-order correction (a sub-cell average of a
    // lobe is the lobe with the sub-cell's variance added): it changes cell masses by about
    // kappa a / 24. Where that is below 1/40 of the Poisson noise of N counts
    // (kappa a / 12 < 0.6 / sqrt(N)) it is left out, and the normalisation is the same at
    // every point.
    const bool widen = kappa * max_sub_cell / 12 > widen_above_;
    const double norm0 = vmf_pdf(kappa, 1.0), dlog0 = dlog_norm(kappa) * kappa;
    // The widened lobe depends on the sub-cell's solid angle alone: on an equal-area grid
    // (HEALPix) it is computed once per lobe, not once per point.
    double widened_for = -1, ke = kappa, norm = norm0, dlog = 0, d_ke = 1;
    double cut_for = -1, min_cosine = -2;  // the 40 e-fold cut below, for the solid angle cut_for
    // Points beyond 40 e-folds are skipped below; a cell whose every point must be (its centre
    // farther from the mean than that angle plus the cell's spread) is skipped whole.
    const double far = 1 - 40 * (1 + kappa * max_sub_cell / 12) / kappa;
    const double reach = far > -1 ? std::acos(far) + levels_.spread(level) : kPi;
    const double cos_reach = reach < kPi ? std::cos(reach) : -2.0;
    const std::vector<Vec3>& centre = levels_.centres();
    const auto [first, last] = levels_.cell_range(mean, reach);
    PointBatch batch;
    for (std::size_t c = first; c < last; ++c) {
      if (dot(mean, centre[c]) < cos_reach) continue;
      for (int j = 0; j < q.per_cell; ++j) {
        const std::size_t i = c * q.per_cell + j;
        const Vec3& x = q.point[i];
        const double a = q.weight[i], cosine = dot(mean, x), f = factor(i, x);
        if (f <= 0) continue;  // below the tangent plane of every exit point of the bin
        // Beyond 40 e-folds below the peak a point adds nothing a double can hold relative
        // to the lobe's mass (and exp would take its slow underflow path).
        if (a != cut_for) cut_for = a, min_cosine = 1 - 40 * (1 + kappa * a / 12) / kappa;
        if (cosine < min_cosine) continue;
        const int k = batch.n++;
        batch.row[k] = row_of_cell_[c], batch.factor[k] = f, batch.x[k] = &x;
        if (widen) {
          if (a != widened_for) {
            const double stretch = 1 + kappa * a / 12;
            widened_for = a, ke = kappa / stretch, d_ke = kappa / (stretch * stretch);
            widened_norm(ke, norm, dlog);
          }
          // d v / d log kappa = v (dlog_norm(ke) + cos - 1) (d ke / d kappa) kappa.
          batch.exponent[k] = ke * (cosine - 1), batch.scale[k] = a * norm;
          batch.theta[k] = dlog + cosine - 1, batch.theta_scale[k] = d_ke, batch.mean_scale[k] = ke;
        } else {
          batch.exponent[k] = kappa * (cosine - 1), batch.scale[k] = a * norm0;
          batch.theta[k] = dlog0 + kappa * (cosine - 1), batch.theta_scale[k] = 1, batch.mean_scale[k] = kappa;
        }
        if (batch.n == PointBatch::kSize) flush(batch, derivatives, out);
      }
    }
    flush(batch, derivatives, out);
  }

  // One copy's integrals, zero outside the rows it reached (`touched`, flagged in `marked`), which
  // are zeroed again after they are folded in: allocated once per evaluation, not once per lobe.
  struct CopyScratch {
    std::vector<double> m, dt, dm;
    std::vector<char> marked;
    std::vector<int> touched;
    CopyScratch(int rows, bool derivatives, bool needed)
        : m(needed ? std::size_t(rows) : 0, 0.0), dt(needed && derivatives ? std::size_t(rows) : 0, 0.0),
          dm(needed && derivatives ? 3 * std::size_t(rows) : 0, 0.0), marked(needed ? std::size_t(rows) : 0, 0) {}
  };

  // One lobe of the bin. In a turning bin (VmfFitOptions::turn) the lobe is the mean of its
  // turned copies, each normalised over the sphere, so its masses are normalised already (totals
  // 1, no pull). The copy at turn t has its mean turned by t and the outward factor of the bin's
  // edges moved by t, and d mass / d mean = R(t)^T d mass / d (R(t) mean). A lobe broad against
  // the turn across the bin (one copy), and every lobe of a bin that stands still, is integrated
  // as it stands. Only the rows a copy reaches are folded in.
  void integrate_bin_lobe(const Vec3& mean, double kappa, const LobeIntegrals& out, CopyScratch& scratch) const {
    const int copies = nodes_needed(kappa);
    if (copies == 1) {
      integrate_lobe(mean, kappa, outward_ ? PointFactor{outward_} : PointFactor{}, out);
      return;
    }
    const bool derivatives = out.d_theta != nullptr;
    std::vector<double>&m = scratch.m, &dt = scratch.dt, &dm = scratch.dm;
    std::vector<char>& marked = scratch.marked;
    std::vector<int>& touched = scratch.touched;
    for (const Node& node : nodes_[std::size_t(copies - 1)]) {
      double t = 0, tt = 0, tm[3] = {0, 0, 0};
      PointFactor factor;
      if (outward_) factor.turned = &node.outward;
      touched.clear();
      integrate_lobe(turn_about_y(mean, node.angle), kappa, factor,
                     {m.data(), derivatives ? dt.data() : nullptr, derivatives ? dm.data() : nullptr, &t, &tt, tm,
                      &touched, marked.data()});
      const double share = t > 1e-150 ? node.weight / t : 0;  // 0: wholly below the moved tangent planes
      const Vec3 pull = share > 0 ? turn_about_y({tm[0] / t, tm[1] / t, tm[2] / t}, -node.angle) : Vec3{};
      for (int r : touched) {
        const std::size_t i = std::size_t(r);
        double* d = derivatives ? &dm[3 * i] : nullptr;
        if (share > 0) {
          out.mass[r] += share * m[i];
          if (derivatives) {
            out.d_theta[r] += share * (dt[i] - m[i] * tt / t);
            const Vec3 back = turn_about_y({d[0], d[1], d[2]}, -node.angle);
            out.d_mean[3 * r] += share * (back.x - m[i] * pull.x);
            out.d_mean[3 * r + 1] += share * (back.y - m[i] * pull.y);
            out.d_mean[3 * r + 2] += share * (back.z - m[i] * pull.z);
          }
        }
        if (derivatives) dt[i] = d[0] = d[1] = d[2] = 0;
        m[i] = 0, marked[i] = 0;
      }
    }
    *out.total = 1, *out.total_theta = 0, out.total_mean[0] = out.total_mean[1] = out.total_mean[2] = 0;
  }

  // Copies of a lobe at n turns across the bin: the midpoints of n equal shares of the exit
  // points (the bin's tilted density in area), turned by the rate times their angle from the
  // bin's middle, for n = 1 .. kMaxTurnNodes.
  struct Node {
    double angle, weight;
    OutwardBin outward;
  };
  void turn_nodes(const BinTurn& turn) {
    const double c0 = std::cos(turn.a0), c1 = std::cos(turn.a1), middle = 0.5 * (turn.a0 + turn.a1);
    for (int n = 1; n <= kMaxTurnNodes; ++n) {
      std::vector<Node> nodes;
      for (int j = 0; j < n; ++j) {
        const double u = tilt_quantile(turn.tilt, (j + 0.5) / n);
        const double angle = turn.rate * (std::acos(std::clamp(c0 + u * (c1 - c0), -1.0, 1.0)) - middle);
        nodes.push_back({angle, 1.0 / n, OutwardBin(turn.a0 + angle, turn.a1 + angle)});
      }
      nodes_.push_back(std::move(nodes));
    }
    span_ = std::abs(turn.rate) * (turn.a1 - turn.a0);
  }
  // Copies enough that neighbours are a lobe width (1 / sqrt(kappa)) apart or closer.
  int nodes_needed(double kappa) const {
    return std::clamp(int(std::ceil(kTurnNodesPerWidth * span_ * std::sqrt(kappa))), 1, kMaxTurnNodes);
  }
  static constexpr int kMaxTurnNodes = 16;
  // Copies one lobe width apart: half as far apart took the fit of tau 1 g 0.9 (1e5 paths) from
  // 5.5-6.7 s to 7.5-10.3 s, and its models moved within 1e-4 either way (docs/fit.md).
  static constexpr double kTurnNodesPerWidth = 1;

 private:
  std::vector<std::vector<Node>> nodes_;  // [n - 1]: n copies; empty: the bin does not turn
  double span_ = 0;                       // the turn across the bin
  const QuadratureLevels& levels_;
  const OutwardFactors* outward_;
  int lobes_;
  std::vector<int> row_of_cell_;
  std::vector<double> count_;
  double total_ = 0;
  double max_sub_cell_[QuadratureLevels::kMaxLevel + 1] = {};  // the largest sub-cell solid angle per level
  double widen_above_ = 0;   // kappa a / 12 beyond which lobes are widened
  double min_log_kappa_, max_log_kappa_;
};

// A pooled neighbour's deviance (PooledBin): PoissonDeviance of its counts with every lobe's
// mean turned by R = R_y(angle), residuals scaled by sqrt(weight) so that its deviance counts
// weight times. R is orthogonal, so d r / d mean = (d r / d (R mean)) R.
//
// With slopes (a sloped pool, VmfFitOptions::sloped) the neighbour d = PooledBin::offset bins
// away sees each lobe's logit and log kappa moved by d times that lobe's slope, and its mean
// turned by d times a turn of its own on top of `angle`: the bin's lobes continued linearly in
// alpha. Three more parameter blocks then follow the means (slopes of the logits, of the log
// kappas, and the turns), shared by all the bin's neighbours; the bin's own deviance does not
// depend on them, so they take up the neighbours' change of shape instead of biasing the bin.
class TurnedDeviance final : public ceres::CostFunction {
 public:
  TurnedDeviance(std::unique_ptr<PoissonDeviance> inner, int lobes, double angle, double weight, bool sloped = false,
                 double offset = 0)
      : inner_(std::move(inner)), lobes_(lobes), angle_(angle), scale_(std::sqrt(weight)), sloped_(sloped),
        offset_(offset) {
    set_num_residuals(inner_->num_residuals());
    *mutable_parameter_block_sizes() = inner_->parameter_block_sizes();
    if (sloped_)
      for (int i = 0; i < 3; ++i) mutable_parameter_block_sizes()->push_back(lobes);
  }

  bool Evaluate(double const* const* params, double* residuals, double** jacobians) const override {
    const std::size_t K = std::size_t(lobes_);
    std::vector<double> turned(3 * K), logits(params[0], params[0] + K), log_kappa(params[1], params[1] + K);
    std::vector<double> c(K, std::cos(angle_)), s(K, std::sin(angle_));
    const double* const* slope = sloped_ ? params + 2 + K : nullptr;  // logits, log kappas, turns
    for (std::size_t k = 0; k < K && slope; ++k) {
      logits[k] += offset_ * slope[0][k], log_kappa[k] += offset_ * slope[1][k];
      c[k] = std::cos(angle_ + offset_ * slope[2][k]), s[k] = std::sin(angle_ + offset_ * slope[2][k]);
    }
    std::vector<const double*> p{logits.data(), log_kappa.data()};
    for (std::size_t k = 0; k < K; ++k) {
      const double* m = params[2 + k];
      double* t = &turned[3 * k];
      t[0] = c[k] * m[0] + s[k] * m[2], t[1] = m[1], t[2] = -s[k] * m[0] + c[k] * m[2];
      p.push_back(t);
    }
    // The slopes' derivatives come from the inner ones, needed even where a block is held.
    const std::size_t rows = std::size_t(num_residuals());
    std::vector<std::vector<double>> own(jacobians && slope ? 2 + K : 0);
    std::vector<double*> inner_jacobians;
    for (std::size_t i = 0; jacobians && i < 2 + K; ++i) {
      inner_jacobians.push_back(jacobians[i]);
      if (!jacobians[i] && slope) own[i].resize(rows * (i < 2 ? K : 3)), inner_jacobians[i] = own[i].data();
    }
    if (!inner_->Evaluate(p.data(), residuals, jacobians ? inner_jacobians.data() : nullptr)) return false;
    for (std::size_t r = 0; r < rows; ++r) residuals[r] *= scale_;
    if (!jacobians) return true;
    for (std::size_t block = 0; block < 2; ++block) {
      double* J = inner_jacobians[block];
      if (!J) continue;
      for (std::size_t i = 0; i < rows * K; ++i) J[i] *= scale_;
      if (slope && jacobians[2 + K + block])  // d / d slope = offset d / d (the moved parameter)
        for (std::size_t i = 0; i < rows * K; ++i) jacobians[2 + K + block][i] = offset_ * J[i];
    }
    for (std::size_t k = 0; k < K; ++k) {
      double* J = inner_jacobians[2 + k];
      if (!J) continue;
      const double* m = params[2 + k];
      // d (R m) / d turn = R' m with R' = [[-s, 0, c], [0, 0, 0], [-c, 0, -s]].
      const double tx = -s[k] * m[0] + c[k] * m[2], tz = -c[k] * m[0] - s[k] * m[2];
      double* turn = slope ? jacobians[2 + K + 2] : nullptr;
      for (std::size_t r = 0; r < rows; ++r) {
        double* row = J + 3 * r;
        const double jx = row[0], jy = row[1], jz = row[2];  // times R_y = [[c, 0, s], [0, 1, 0], [-s, 0, c]]
        if (turn) turn[r * K + k] = scale_ * offset_ * (jx * tx + jz * tz);
        row[0] = scale_ * (jx * c[k] - jz * s[k]), row[1] = scale_ * jy, row[2] = scale_ * (jx * s[k] + jz * c[k]);
      }
    }
    return true;
  }

 private:
  std::unique_ptr<PoissonDeviance> inner_;
  int lobes_;
  double angle_, scale_;
  bool sloped_;
  double offset_;
};

// Banerjee et al. (2005): kappa from the mean resultant length R in 3D.
double kappa_from_resultant(double r) {
  r = std::clamp(r, 0.0, 1 - 1e-12);
  return r * (3 - r * r) / (1 - r * r);
}

// EM for a vMF mixture on cell centres weighted by counts (Banerjee et al. 2005): soft
// assignments refine the k-means start, so Levenberg-Marquardt starts near the optimum.
void em_on_cells(const std::vector<double>& counts, const std::vector<Vec3>& centre,
                 std::vector<VmfLobe>& lobes, int iterations, double max_kappa) {
  const int K = int(lobes.size());
  std::vector<double> r(K);
  for (int it = 0; it < iterations; ++it) {
    std::vector<Vec3> sum(K, Vec3{0, 0, 0});
    std::vector<double> mass(K, 0);
    for (std::size_t c = 0; c < counts.size(); ++c) {
      if (counts[c] <= 0) continue;
      double norm = 0;
      for (int k = 0; k < K; ++k) norm += r[k] = lobes[k].weight * vmf_pdf(lobes[k].kappa, dot(lobes[k].mean, centre[c]));
      if (norm <= 0) continue;
      for (int k = 0; k < K; ++k) {
        double w = counts[c] * r[k] / norm;
        mass[k] += w;
        sum[k] = {sum[k].x + w * centre[c].x, sum[k].y + w * centre[c].y, sum[k].z + w * centre[c].z};
      }
    }
    double total = 0;
    for (double m : mass) total += m;
    for (int k = 0; k < K; ++k) {
      double len = length(sum[k]);
      if (mass[k] <= 1e-9 * total || len <= 0) continue;  // a starved lobe keeps its place
      lobes[k] = {mass[k] / total, std::min(kappa_from_resultant(len / mass[k]), max_kappa),
                  {sum[k].x / len, sum[k].y / len, sum[k].z / len}};
    }
  }
}

}  // namespace

std::vector<VmfLobe> initial_lobes(const std::vector<double>& counts, const CellQuadrature& q, int K) {
  const std::size_t cells = counts.size();
  // Counts at cell centres resolve no lobe narrower than a cell: a cluster of one cell has a
  // resultant of 1 and would start as a point lobe (kappa at the cap) that the binned
  // likelihood can no longer move or widen, holding that cell's count while the other lobes
  // fit the rest around it. Start lobes are at most as narrow as one mean cell (2 pi / kappa
  // = 4 pi / cells); the likelihood stage narrows them where the data ask for it.
  const double resolved = std::min(kMaxStartKappa, 0.5 * double(cells));
  std::vector<Vec3> centre(cells);
  for (std::size_t c = 0; c < cells; ++c) centre[c] = cell_centre(q, c);
  // Seeds: the fullest cell, then farthest-first weighted by counts.
  std::vector<Vec3> mean;
  mean.push_back(centre[std::max_element(counts.begin(), counts.end()) - counts.begin()]);
  while (int(mean.size()) < K) {
    double best = -1;
    std::size_t pick = 0;
    for (std::size_t c = 0; c < cells; ++c) {
      double nearest = -1;
      for (const Vec3& m : mean) nearest = std::max(nearest, dot(m, centre[c]));
      double score = counts[c] * (1 - nearest);
      if (score > best) best = score, pick = c;
    }
    mean.push_back(centre[pick]);
  }
  std::vector<VmfLobe> lobes(K);
  std::vector<int> owner(cells, 0);
  for (int iteration = 0; iteration < 20; ++iteration) {
    for (std::size_t c = 0; c < cells; ++c) {
      int best = 0;
      for (int k = 1; k < K; ++k)
        if (dot(mean[k], centre[c]) > dot(mean[best], centre[c])) best = k;
      owner[c] = best;
    }
    std::vector<Vec3> sum(K, Vec3{0, 0, 0});
    std::vector<double> mass(K, 0);
    for (std::size_t c = 0; c < cells; ++c) {
      Vec3& s = sum[owner[c]];
      s = {s.x + counts[c] * centre[c].x, s.y + counts[c] * centre[c].y, s.z + counts[c] * centre[c].z};
      mass[owner[c]] += counts[c];
    }
    double total = 0;
    for (double m : mass) total += m;
    for (int k = 0; k < K; ++k) {
      double len = length(sum[k]);
      if (mass[k] <= 0 || len <= 0) {  // an empty cluster: a faint uniform lobe
        lobes[k] = {1e-3, 1e-3, mean[k]};
        continue;
      }
      mean[k] = {sum[k].x / len, sum[k].y / len, sum[k].z / len};
      lobes[k] = {mass[k] / total, std::min(kappa_from_resultant(len / mass[k]), resolved), mean[k]};
    }
  }
  double total = 0;
  for (const VmfLobe& l : lobes) total += l.weight;
  for (VmfLobe& l : lobes) l.weight /= total;
  em_on_cells(counts, centre, lobes, 30, resolved);
  return lobes;
}

QuadratureLevels::QuadratureLevels(const DirectionGrid& grid) {
  for (int level = 0; level <= kMaxLevel; ++level) levels_.push_back(grid.quadrature(level));
  for (std::size_t c = 0; c < levels_[0].point.size() / std::size_t(levels_[0].per_cell); ++c)
    centres_.push_back(cell_centre(levels_[0], c));
  lowest_z_up_to_.resize(centres_.size());
  highest_z_from_.resize(centres_.size());
  for (std::size_t c = 0; c < centres_.size(); ++c)
    lowest_z_up_to_[c] = std::min(centres_[c].z, c > 0 ? lowest_z_up_to_[c - 1] : 2.0);
  for (std::size_t c = centres_.size(); c-- > 0;)
    highest_z_from_[c] = std::max(centres_[c].z, c + 1 < centres_.size() ? highest_z_from_[c + 1] : -2.0);
  for (const CellQuadrature& q : levels_) {
    double widest = 1;  // the smallest cosine between a centre and a point of its cell
    for (std::size_t i = 0; i < q.point.size(); ++i)
      widest = std::min(widest, dot(centres_[i / std::size_t(q.per_cell)], q.point[i]));
    spread_.push_back(std::acos(std::clamp(widest, -1.0, 1.0)) + 1e-9);
  }
  const CellQuadrature& finest = levels_[kMaxLevel];
  for (int level = 0; level < kMaxLevel; ++level) {
    const CellQuadrature& q = levels_[std::size_t(level)];
    for (std::size_t i = 0; i < finest.point.size(); ++i) {
      const std::size_t first = i / std::size_t(finest.per_cell) * std::size_t(q.per_cell);
      std::size_t nearest = first;
      for (std::size_t k = first + 1; k < first + std::size_t(q.per_cell); ++k)
        if (dot(q.point[k], finest.point[i]) > dot(q.point[nearest], finest.point[i])) nearest = k;
      finest_parent_[std::size_t(level)].push_back(std::uint32_t(nearest));
    }
  }
  std::vector<double> omega = grid.solid_angles();
  cell_solid_angle_ = *std::max_element(omega.begin(), omega.end());
  pole_cell_ = grid.cell({0, 0, 1});
}

std::pair<std::size_t, std::size_t> QuadratureLevels::cell_range(const Vec3& mean, double reach) const {
  if (reach >= kPi) return {0, centres_.size()};
  // A centre within `reach` of the mean has its polar angle within `reach` of the mean's; the
  // margin covers rounding.
  const double polar = std::acos(std::clamp(mean.z, -1.0, 1.0)), margin = 1e-9;
  const double z_high = std::cos(std::max(0.0, polar - reach)) + margin;
  const double z_low = std::cos(std::min(kPi, polar + reach)) - margin;
  // Cells before the first whose running lowest z is at most z_high all lie above the band;
  // cells after the last whose highest z from there on is at least z_low all lie below it.
  const auto first = std::partition_point(lowest_z_up_to_.begin(), lowest_z_up_to_.end(),
                                          [&](double z) { return z > z_high; });
  const auto last = std::partition_point(highest_z_from_.begin(), highest_z_from_.end(),
                                         [&](double z) { return z >= z_low; });
  const std::size_t a = std::size_t(first - lowest_z_up_to_.begin()), b = std::size_t(last - highest_z_from_.begin());
  return {a, std::max(a, b)};
}

int QuadratureLevels::level_for_kappa(double kappa, double counts) const {
  const double limit = 0.25 * std::pow(std::max(counts, 1.0), -0.25);
  int level = 0;
  while (level < kMaxLevel && kappa * cell_solid_angle_ / (12 << (2 * level)) > limit) ++level;
  return level;
}

namespace {

VmfFitResult solve(const std::vector<double>& counts, const QuadratureLevels& levels,
                   const std::vector<VmfLobe>& start, const VmfFitOptions& options) {
  const int K = int(start.size());
  std::vector<double> logits(K), log_kappa(K), means(3 * K);
  for (int k = 0; k < K; ++k) {
    logits[k] = std::log(std::max(start[k].weight, 1e-12));
    log_kappa[k] = std::log(std::clamp(start[k].kappa, options.min_kappa * 10, std::min(kMaxStartKappa, options.max_kappa / 10)));
    means[3 * k] = start[k].mean.x, means[3 * k + 1] = start[k].mean.y, means[3 * k + 2] = start[k].mean.z;
  }
  ceres::Problem::Options problem_options;
  problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(problem_options);
  std::vector<double*> blocks = {logits.data(), log_kappa.data()};
  for (int k = 0; k < K; ++k) blocks.push_back(&means[3 * k]);
  problem.AddResidualBlock(
      new PoissonDeviance(levels, counts, K, options.outward, options.min_kappa, options.max_kappa, options.turn),
      nullptr, blocks);
  // Slopes of the logits, the log kappas and the turns (sloped pools), from none.
  std::vector<double> slopes(options.sloped && !options.pooled.empty() ? 3 * std::size_t(K) : 0, 0.0);
  std::vector<double*> pooled_blocks = blocks;
  for (std::size_t i = 0; i < slopes.size(); i += std::size_t(K)) pooled_blocks.push_back(&slopes[i]);
  for (const PooledBin& n : options.pooled)
    problem.AddResidualBlock(
        new TurnedDeviance(std::make_unique<PoissonDeviance>(levels, *n.counts, K, n.outward, options.min_kappa,
                                                             options.max_kappa, n.turn),
                           K, n.angle, n.weight, !slopes.empty(), n.offset),
        nullptr, pooled_blocks);
  ceres::SphereManifold<3> sphere;
  for (int k = 0; k < K; ++k) problem.SetManifold(&means[3 * k], &sphere);
  // The weights are a softmax of the logits, unchanged when all move together: the first is
  // held, so that J^T J has no null direction and the normal equations (a quarter of the work
  // of a QR of the cells-by-parameters Jacobian) can be solved by Cholesky.
  std::unique_ptr<ceres::SubsetManifold> first_logit_held;
  if (K == 1) {
    problem.SetParameterBlockConstant(logits.data());
    if (!slopes.empty()) problem.SetParameterBlockConstant(slopes.data());
  } else {
    first_logit_held = std::make_unique<ceres::SubsetManifold>(K, std::vector<int>{0});
    problem.SetManifold(logits.data(), first_logit_held.get());
    if (!slopes.empty()) problem.SetManifold(slopes.data(), first_logit_held.get());
  }

  ceres::Solver::Options solver;
  solver.linear_solver_type = ceres::DENSE_NORMAL_CHOLESKY;
  solver.max_num_iterations = options.max_iterations;
  solver.function_tolerance = options.function_tolerance;
  solver.num_threads = 1;
  solver.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(solver, &problem, &summary);

  VmfFitResult result;
  result.iterations = int(summary.iterations.size());
  result.deviance = 2 * summary.final_cost;
  // As the deviance saw them: clamped to their bounds.
  for (int k = 0; k < K; ++k) {
    logits[k] = std::clamp(logits[k], -kMaxLogit, kMaxLogit);
    log_kappa[k] = std::clamp(log_kappa[k], std::log(options.min_kappa), std::log(options.max_kappa));
  }
  double max_logit = *std::max_element(logits.begin(), logits.end()), sum = 0;
  for (int k = 0; k < K; ++k) sum += std::exp(logits[k] - max_logit);
  for (int k = 0; k < K; ++k) {
    result.lobes.push_back({std::exp(logits[k] - max_logit) / sum, std::exp(log_kappa[k]),
                            normalize({means[3 * k], means[3 * k + 1], means[3 * k + 2]})});
  }
  return result;
}

}  // namespace

OutwardFactors outward_factors(const QuadratureLevels& levels, double a0, double a1) {
  OutwardFactors f;
  const OutwardBin factor(a0, a1);
  for (int level = 0; level <= QuadratureLevels::kMaxLevel; ++level)
    for (const Vec3& x : levels.at(level).point) f[std::size_t(level)].push_back(factor(x));
  return f;
}

OutwardFactors outward_cell_means(const QuadratureLevels& levels, double a0, double a1) {
  constexpr int finest = QuadratureLevels::kMaxLevel;
  OutwardFactors f;
  const OutwardBin factor(a0, a1);
  const CellQuadrature& q = levels.at(finest);
  for (const Vec3& x : q.point) f[finest].push_back(factor(x));
  for (int level = 0; level < finest; ++level) {
    const std::vector<std::uint32_t>& parent = levels.finest_parent(level);
    std::vector<double> weighted(levels.at(level).point.size(), 0.0), area(weighted.size(), 0.0);
    for (std::size_t i = 0; i < q.point.size(); ++i)
      weighted[parent[i]] += q.weight[i] * f[finest][i], area[parent[i]] += q.weight[i];
    // (Every sub-cell holds finest points on both grids; the point value stands in otherwise.)
    const CellQuadrature& coarse = levels.at(level);
    for (std::size_t k = 0; k < weighted.size(); ++k)
      f[std::size_t(level)].push_back(area[k] > 0 ? weighted[k] / area[k] : factor(coarse.point[k]));
  }
  return f;
}

std::vector<double> vmf_cell_probabilities(const std::vector<VmfLobe>& lobes, const QuadratureLevels& levels,
                                           double counts, const OutwardFactors* outward) {
  std::vector<double> p(levels.at(0).point.size(), 0.0);
  for (const VmfLobe& l : lobes) {
    if (l.weight <= 0) continue;
    const int level = levels.level_for_kappa(l.kappa, counts);
    const std::vector<double> one = vmf_cell_probabilities({{1.0, l.kappa, l.mean}}, levels.at(level),
                                                           outward ? &(*outward)[std::size_t(level)] : nullptr);
    for (std::size_t c = 0; c < p.size(); ++c) p[c] += l.weight * one[c];
  }
  return p;
}

std::vector<double> vmf_bin_probabilities(const std::vector<VmfLobe>& lobes, const QuadratureLevels& levels,
                                          double counts, const OutwardFactors* outward, const BinTurn& turn) {
  const std::vector<double> every_cell(levels.centres().size(), 1.0);
  PoissonDeviance bin(levels, every_cell, int(lobes.size()), outward, 1e-6, 1e8, &turn);
  return bin.probabilities(lobes, counts);
}

std::vector<VmfLobe> grow_lobes(std::vector<VmfLobe> lobes, int K) {
  // Lobes of zero weight (a bin with fewer escapes than lobes) are dropped first.
  lobes.erase(std::remove_if(lobes.begin(), lobes.end(), [](const VmfLobe& l) { return l.weight <= 0; }), lobes.end());
  if (int(lobes.size()) > K) lobes.resize(std::size_t(K));
  while (int(lobes.size()) < K) {
    if (lobes.empty()) {
      lobes.push_back({1, 1e-3, {0, 0, 1}});
      continue;
    }
    // The heaviest lobe becomes two, half a standard deviation to each side of its mean, so
    // the likelihood's gradient can pull them apart.
    VmfLobe& l = *std::max_element(lobes.begin(), lobes.end(), [](const VmfLobe& a, const VmfLobe& b) { return a.weight < b.weight; });
    Vec3 b1, b2;
    orthonormal_basis(l.mean, b1, b2);
    const double offset = std::min(0.5, 0.5 / std::sqrt(std::max(l.kappa, 1e-6)));
    VmfLobe twin = l;
    l.weight *= 0.5, twin.weight = l.weight;
    l.mean = normalize({l.mean.x + offset * b1.x, l.mean.y + offset * b1.y, l.mean.z + offset * b1.z});
    twin.mean = normalize({twin.mean.x - offset * b1.x, twin.mean.y - offset * b1.y, twin.mean.z - offset * b1.z});
    lobes.push_back(twin);
  }
  double total = 0;
  for (const VmfLobe& l : lobes) total += l.weight;
  for (VmfLobe& l : lobes) l.weight /= total;
  return lobes;
}

VmfFitResult fit_vmf_from(const std::vector<double>& counts, const QuadratureLevels& levels,
                          const std::vector<VmfLobe>& start, const VmfFitOptions& options) {
  return solve(counts, levels, start, options);
}

VmfFitResult fit_vmf(const std::vector<double>& counts, const QuadratureLevels& levels, int K,
                     const VmfFitOptions& options) {
  if (!options.outward) return solve(counts, levels, initial_lobes(counts, levels.at(0), K), options);
  // Hemispherical lobes have more poor local optima than plain ones: K lobes grow from a fit of
  // half as many (the heaviest split), down to two from k-means.
  if (K > 2) return solve(counts, levels, grow_lobes(fit_vmf(counts, levels, (K + 1) / 2, options).lobes, K), options);
  // They are multiplied by the outward factor, so they start from the counts with that factor
  // divided out (floored, so that grazing cells do not dominate): the shape the lobes
  // themselves must take.
  std::vector<double> lobe_counts(counts);
  const std::vector<double>& factor = (*options.outward)[0];
  for (std::size_t c = 0; c < lobe_counts.size(); ++c) lobe_counts[c] = factor[c] > 0 ? counts[c] / std::max(factor[c], 0.1) : 0.0;
  return solve(counts, levels, initial_lobes(lobe_counts, levels.at(0), K), options);
}

}  // namespace stf::fit
