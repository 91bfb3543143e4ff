#pragma once
// Uniform quintic B-splines over Eigen vectors: C4-continuous curves whose value and first four
// time derivatives are exact polynomials, evaluated in closed form.
//
// Matrix form (Qin, "General matrix representations for B-splines", The Visual Computer 16(3),
// 2000, Sec. 3): on segment i, with u = (t - t0) / dt - i in [0, 1),
//
//   p(t) = sum_j  [1 u u^2 u^3 u^4 u^5] * M.col(j) * P_{i+j},     j = 0..5,
//   M(r, j) = 1/5! * C(5, r) * sum_{s=j}^{5} (-1)^(s-j) C(6, s-j) (5-s)^(5-r),
//
// and the n-th time derivative differentiates the power row, d^n/dt^n u^r = r!/(r-n)! u^(r-n) /
// dt^n. The basis functions are non-negative and sum to one, so the curve stays in the convex hull
// of the six control points of each segment (a box containing the control points contains the
// curve).
//
// Time: control point j "belongs" to time t0 + (j - 2) * dt (its Greville abscissa); with
// P_j = f(t0 + (j - 2) dt) the spline reproduces every polynomial f of degree <= 1 exactly (and
// constants trivially). The curve is defined on [t_min(), t_max()] = [t0, t0 + (n - 5) dt] for n
// control points; evaluation outside that span is a bug (MAV_CHECK), the spline never
// extrapolates silently.

#include <algorithm>
#include <array>
#include <cmath>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "mav/common/check.h"
#include "mav/common/status.h"

namespace mav::geometry {

template <int Dim>
class UniformQuinticBSpline {
 public:
  static_assert(Dim > 0, "dimension must be positive");
  using Vector = Eigen::Matrix<double, Dim, 1>;
  static constexpr int kDegree = 5;
  static constexpr int kOrder = kDegree + 1;  // control points per segment
  // Derivatives 0..4 are continuous; the 5th is piecewise constant (it jumps at knots).
  static constexpr int kMaxDerivative = 5;

  // An empty spline (num_control_points() == 0); Evaluate() on it is a bug.
  UniformQuinticBSpline() = default;

  // Preconditions (MAV_CHECK): dt_s > 0 and finite, t0_s finite, at least kOrder control points,
  // all control points finite. Use Create() when the input comes from a user.
  UniformQuinticBSpline(double t0_s, double dt_s, std::vector<Vector> control_points)
      : t0_(t0_s), dt_(dt_s), ctrl_(std::move(control_points)) {
    std::string why;
    MAV_CHECK(CheckArguments(t0_, dt_, ctrl_, &why)) << why;
  }

  // As the constructor, but InvalidArgument (naming the argument) instead of aborting.
  static Result<UniformQuinticBSpline> Create(double t0_s, double dt_s,
                                              std::vector<Vector> control_points) {
    std::string why;
    if (!CheckArguments(t0_s, dt_s, control_points, &why)) return Status::InvalidArgument(why);
    return UniformQuinticBSpline(t0_s, dt_s, std::move(control_points));
  }

  // Number of control points needed to cover `duration_s` (>= 0) with knots every `dt_s`.
  static int NumControlPointsFor(double duration_s, double dt_s) {
    MAV_CHECK(duration_s >= 0 && dt_s > 0) << "duration " << duration_s << ", dt " << dt_s;
    const int segments = std::max(1, static_cast<int>(std::ceil(duration_s / dt_s - 1e-9)));
    return segments + kDegree;
  }

  double t0() const { return t0_; }
  double dt() const { return dt_; }
  double t_min() const { return t0_; }
  double t_max() const { return t0_ + num_segments() * dt_; }
  int num_segments() const { return ctrl_.empty() ? 0 : static_cast<int>(ctrl_.size()) - kDegree; }
  int num_control_points() const { return static_cast<int>(ctrl_.size()); }
  const std::vector<Vector>& control_points() const { return ctrl_; }
  // Time the control point `j` is associated with (see the file comment).
  double ControlPointTime(int j) const { return t0_ + (j - 2) * dt_; }

  // The `derivative`-th time derivative (0 = value, units of the control points per s^n) at t_s.
  // Preconditions: 0 <= derivative <= kMaxDerivative, t_s in [t_min(), t_max()] (a relative slack
  // of 1e-9 dt is tolerated and clamped).
  Vector Evaluate(double t_s, int derivative = 0) const {
    MAV_CHECK(derivative >= 0 && derivative <= kMaxDerivative)
        << "derivative " << derivative << " outside 0.." << kMaxDerivative;
    Vector out;
    EvaluateImpl(t_s, derivative, derivative, &out);
    return out;
  }

  // Value and derivatives 0..max_derivative at t_s in one pass: out[n] = n-th derivative.
  template <int MaxDerivative>
  std::array<Vector, MaxDerivative + 1> EvaluateUpTo(double t_s) const {
    static_assert(MaxDerivative >= 0 && MaxDerivative <= kMaxDerivative, "derivative 0..5");
    std::array<Vector, MaxDerivative + 1> out;
    EvaluateImpl(t_s, 0, MaxDerivative, out.data());
    return out;
  }

  // Qin's blending matrix M (rows: powers of u, columns: the segment's 6 control points).
  static const Eigen::Matrix<double, kOrder, kOrder>& BlendingMatrix() {
    static const Eigen::Matrix<double, kOrder, kOrder> m = ComputeBlendingMatrix();
    return m;
  }

 private:
  static bool CheckArguments(double t0, double dt, const std::vector<Vector>& ctrl,
                             std::string* why) {
    std::ostringstream msg;
    if (!std::isfinite(t0)) {
      msg << "t0_s: must be finite, got " << t0;
    } else if (!(dt > 0) || !std::isfinite(dt)) {
      msg << "dt_s: knot spacing must be positive and finite, got " << dt;
    } else if (static_cast<int>(ctrl.size()) < kOrder) {
      msg << "control_points: a quintic B-spline needs at least " << kOrder
          << " control points, got " << ctrl.size();
    } else {
      for (size_t j = 0; j < ctrl.size(); ++j) {
        if (!ctrl[j].allFinite()) {
          msg << "control_points[" << j << "]: not finite";
          break;
        }
      }
    }
    const std::string text = msg.str();
    if (text.empty()) return true;
    if (why) *why = text;
    return false;
  }

  static double Binomial(int n, int k) {
    double r = 1;
    for (int i = 1; i <= k; ++i) r = r * (n - k + i) / i;
    return r;
  }

  static Eigen::Matrix<double, kOrder, kOrder> ComputeBlendingMatrix() {
    const int k = kOrder;
    double factorial = 1;
    for (int i = 2; i < k; ++i) factorial *= i;
    Eigen::Matrix<double, kOrder, kOrder> m;
    for (int r = 0; r < k; ++r) {
      for (int j = 0; j < k; ++j) {
        double sum = 0;
        for (int s = j; s < k; ++s) {
          const double sign = ((s - j) % 2 == 0) ? 1.0 : -1.0;
          sum += sign * Binomial(k, s - j) * std::pow(k - s - 1.0, k - 1 - r);  // pow(0, 0) == 1
        }
        m(r, j) = Binomial(k - 1, r) * sum / factorial;
      }
    }
    return m;
  }

  // Writes derivatives lo..hi into out[0..hi-lo].
  void EvaluateImpl(double t_s, int lo, int hi, Vector* out) const {
    MAV_CHECK(!ctrl_.empty()) << "Evaluate() on an empty spline";
    const double slack = 1e-9 * dt_;
    MAV_CHECK(t_s >= t_min() - slack && t_s <= t_max() + slack)
        << "time " << t_s << " s outside the spline's span [" << t_min() << ", " << t_max()
        << "] s";
    const double s = (t_s - t0_) / dt_;
    int segment = static_cast<int>(std::floor(s));
    segment = std::clamp(segment, 0, num_segments() - 1);
    const double u = std::clamp(s - segment, 0.0, 1.0);

    // powers[r] = u^r.
    std::array<double, kOrder> powers;
    powers[0] = 1;
    for (int r = 1; r < kOrder; ++r) powers[r] = powers[r - 1] * u;

    const Eigen::Matrix<double, kOrder, kOrder>& m = BlendingMatrix();
    for (int n = lo; n <= hi; ++n) {
      // Row vector d^n/du^n [1 u .. u^5], scaled by 1/dt^n for the time derivative.
      Eigen::Matrix<double, 1, kOrder> row = Eigen::Matrix<double, 1, kOrder>::Zero();
      for (int r = n; r < kOrder; ++r) {
        double falling = 1;  // r! / (r - n)!
        for (int q = 0; q < n; ++q) falling *= (r - q);
        row[r] = falling * powers[r - n];
      }
      const Eigen::Matrix<double, 1, kOrder> weights = row * m / std::pow(dt_, n);
      Vector value = Vector::Zero();
      for (int j = 0; j < kOrder; ++j) value += weights[j] * ctrl_[segment + j];
      out[n - lo] = value;
    }
  }

  double t0_ = 0;
  double dt_ = 1;
  std::vector<Vector> ctrl_;
};

}  // namespace mav::geometry
