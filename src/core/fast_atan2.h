// Private helper of the core: a cheaper atan2 for per-point bearings (consistency, re-binning).
#pragma once

#include <algorithm>
#include <cmath>

namespace lidar_deskew::core::detail {

/// [rad] largest error of fastAtan2 (with margin).
constexpr double kFastAtan2Error = 5e-8;

/// atan2(y, x) [rad] in [-pi, pi] to within kFastAtan2Error, a few times cheaper than libm's (which took a
/// fifth of the consistency measure's time and most of the re-binning's): an odd polynomial for atan on
/// [0, 1] (least-squares fitted on Chebyshev nodes, error 4.1e-8 rad) and the octant's symmetries.
inline double fastAtan2(double y, double x) {
  const double ax = std::abs(x), ay = std::abs(y);
  const double high = std::max(ax, ay);
  if (high == 0.0)
    return 0.0;
  const double a = std::min(ax, ay) / high;
  const double s = a * a;
  double r = a * (0.99999943684314718 +
                  s * (-0.33330106677687926 +
                       s * (0.19948508985754437 +
                            s * (-0.1391580226062557 +
                                 s * (0.096562564702695933 +
                                      s * (-0.056063176726315958 +
                                           s * (0.02194661103058218 + s * -0.0040733094638858158)))))));
  if (ay > ax)
    r = M_PI_2 - r;
  if (x < 0.0)
    r = M_PI - r;
  return y < 0.0 ? -r : r;
}

}  // namespace lidar_deskew::core::detail
