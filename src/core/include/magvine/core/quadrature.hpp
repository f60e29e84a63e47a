#pragma once
/// Gauss–Legendre quadrature: the one home of its nodes and weights (the cylinder's reference field, the
/// magnet–magnet wrench).

#include <vector>

namespace magvine {

/// Nodes x and weights w of the n-point Gauss–Legendre rule on [−1, 1] (Newton iteration on P_n; exact for
/// polynomials of degree ≤ 2n − 1). n ≥ 1.
void gauss_legendre(int n, std::vector<double>& x, std::vector<double>& w);

}  // namespace magvine
