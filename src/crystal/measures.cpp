#include "subslip/crystal/measures.hpp"

#include <Eigen/LU>
#include <cmath>
#include <stdexcept>
#include <string>

namespace subslip::crystal {

namespace {

using Mat3 = Eigen::Matrix3d;
using RowMajor3 = Eigen::Matrix<double, 3, 3, Eigen::RowMajor>;

Mat3 deviator_of_symmetric_part(const Mat3& t) {
  const Mat3 sym = 0.5 * (t + t.transpose());
  return sym - sym.trace() / 3.0 * Mat3::Identity();
}

template <class Measure>
std::vector<double> per_tensor(std::span<const double> tensors, Measure measure) {
  if (tensors.size() % 9 != 0) {
    throw std::invalid_argument("von Mises: " + std::to_string(tensors.size()) +
                                " values are no whole number of 3x3 tensors");
  }
  std::vector<double> out(tensors.size() / 9);
  for (std::size_t k = 0; k < out.size(); ++k) {
    const Mat3 t = Eigen::Map<const RowMajor3>(tensors.data() + 9 * k);
    out[k] = measure(t);
  }
  return out;
}

void check_size(const char* what, std::size_t have, std::size_t want) {
  if (have != want) {
    throw std::invalid_argument(std::string(what) + ": " + std::to_string(have) +
                                " values where the shape needs " + std::to_string(want));
  }
}

// sym(s (x) m) of every row [s, m] of `systems`.
std::vector<Mat3> schmid_tensors(std::span<const double> systems) {
  std::vector<Mat3> out(systems.size() / 6);
  for (std::size_t a = 0; a < out.size(); ++a) {
    const Eigen::Vector3d s(systems[6 * a], systems[6 * a + 1], systems[6 * a + 2]);
    const Eigen::Vector3d m(systems[6 * a + 3], systems[6 * a + 4], systems[6 * a + 5]);
    const Mat3 p = s * m.transpose();
    out[a] = 0.5 * (p + p.transpose());
  }
  return out;
}

}  // namespace

Mat3 first_piola_stress(const Mat3& cauchy, const Mat3& f) {
  // sigma F^-T = (F^-1 sigma^T)^T: one LU solve, no inverse.
  const Eigen::PartialPivLU<Mat3> lu(f);
  return lu.determinant() * lu.solve(cauchy.transpose()).transpose();
}

double von_mises_stress(const Eigen::Matrix3d& stress) {
  return std::sqrt(1.5 * deviator_of_symmetric_part(stress).squaredNorm());
}

double von_mises_strain(const Eigen::Matrix3d& strain) {
  return std::sqrt(2.0 / 3.0 * deviator_of_symmetric_part(strain).squaredNorm());
}

std::vector<double> von_mises_stress(std::span<const double> tensors) {
  return per_tensor(tensors, [](const Mat3& t) { return von_mises_stress(t); });
}

std::vector<double> von_mises_strain(std::span<const double> tensors) {
  return per_tensor(tensors, [](const Mat3& t) { return von_mises_strain(t); });
}

std::vector<double> equivalent_plastic_strain(std::span<const double> slip, std::size_t rows,
                                              std::size_t grains, std::span<const double> systems) {
  if (systems.size() % 6 != 0) {
    throw std::invalid_argument("slip systems: " + std::to_string(systems.size()) +
                                " values are no whole number of rows [s, m] of 6");
  }
  const std::vector<Mat3> schmid = schmid_tensors(systems);
  const std::size_t n = schmid.size();
  check_size("slip", slip.size(), rows * grains * n);
  std::vector<double> out(rows * grains, 0.0);
  for (std::size_t row = 1; row < rows; ++row) {
    for (std::size_t g = 0; g < grains; ++g) {
      const double* now = slip.data() + (row * grains + g) * n;
      const double* before = now - grains * n;
      Mat3 d_strain = Mat3::Zero();
      for (std::size_t a = 0; a < n; ++a) d_strain += (now[a] - before[a]) * schmid[a];
      const double d_eq = std::sqrt(2.0 / 3.0 * d_strain.squaredNorm());
      out[row * grains + g] = out[(row - 1) * grains + g] + d_eq;
    }
  }
  return out;
}

std::vector<double> weighted_mean_abs(std::span<const double> values, std::size_t rows,
                                      std::size_t grains, std::span<const double> weights) {
  check_size("weights", weights.size(), grains);
  const std::size_t k = rows * grains == 0 ? 0 : values.size() / (rows * grains);
  check_size("per-grain values", values.size(), rows * grains * k);
  double total = 0.0;
  for (double w : weights) total += w;
  std::vector<double> out(rows * k, 0.0);
  for (std::size_t row = 0; row < rows; ++row) {
    for (std::size_t g = 0; g < grains; ++g) {
      const double w = weights[g] / total;
      for (std::size_t c = 0; c < k; ++c)
        out[row * k + c] += w * std::abs(values[(row * grains + g) * k + c]);
    }
  }
  return out;
}

}  // namespace subslip::crystal
