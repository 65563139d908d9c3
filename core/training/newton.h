#pragma once
// Newton's method with step halving, for the convex losses the calibration and the learned
// codeword weights minimise (logistic regressions with a ridge).
#include <Eigen/Dense>

namespace ism {

// From `w`: each step solves hessian * delta = gradient (`derivatives(w, gradient, hessian)`),
// then halves until `loss` falls (giving up below 1e-6 of a step); stops after `iterations` steps
// or once the loss falls by less than `tolerance`.
template <class Loss, class Derivatives>
Eigen::VectorXd newtonMinimise(Eigen::VectorXd w, const Loss& loss, const Derivatives& derivatives, int iterations,
                               double tolerance) {
  double current = loss(w);
  Eigen::VectorXd gradient;
  Eigen::MatrixXd hessian;
  for (int iteration = 0; iteration < iterations; ++iteration) {
    derivatives(w, gradient, hessian);
    const Eigen::VectorXd delta = hessian.ldlt().solve(gradient);
    double step = 1;
    while (step > 1e-6 && !(loss(w - step * delta) < current)) step /= 2;
    if (step <= 1e-6) break;
    w -= step * delta;
    const double next = loss(w);
    const bool converged = current - next < tolerance;
    current = next;
    if (converged) break;
  }
  return w;
}

}  // namespace ism
