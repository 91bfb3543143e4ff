#pragma once
// Numeric derivatives for tests that check analytic Jacobians (as Basalt's test_jacobian does):
// central differences of a function of a vector, f(x + h e_k) - f(x - h e_k) / 2h per column.
// For a function on a Lie group, pass the perturbation through the function itself, e.g.
//   NumericJacobian<4, 6>([&](const Vector6d& d) { return Residual(SE3::Exp(d) * T); },
//                         Vector6d::Zero());
// `h` may be one step for every column or one per column (different units, e.g. m and rad).

#include <Eigen/Core>

namespace mav::test_support {

template <int M, int N, typename F>
Eigen::Matrix<double, M, N> NumericJacobian(const F& f, const Eigen::Matrix<double, N, 1>& x,
                                            const Eigen::Matrix<double, N, 1>& h) {
  Eigen::Matrix<double, M, N> jacobian;
  for (int k = 0; k < N; ++k) {
    Eigen::Matrix<double, N, 1> d = Eigen::Matrix<double, N, 1>::Zero();
    d[k] = h[k];
    const Eigen::Matrix<double, M, 1> plus = f(Eigen::Matrix<double, N, 1>(x + d));
    const Eigen::Matrix<double, M, 1> minus = f(Eigen::Matrix<double, N, 1>(x - d));
    jacobian.col(k) = (plus - minus) / (2 * h[k]);
  }
  return jacobian;
}

template <int M, int N, typename F>
Eigen::Matrix<double, M, N> NumericJacobian(const F& f, const Eigen::Matrix<double, N, 1>& x,
                                            double h = 1e-6) {
  return NumericJacobian<M, N>(f, x, Eigen::Matrix<double, N, 1>::Constant(h));
}

}  // namespace mav::test_support
