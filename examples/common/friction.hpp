// Examples: the friction options every forming example takes (one law for
// all its tools; the library allows a law per tool).
#pragma once

#include <CLI/CLI.hpp>

#include <string>

#include <maxentflow/maxentflow.hpp>

namespace maxentflow::examples {

struct FrictionOptions {
  bool sticking = false;
  double m = -1.0;         ///< Tresca shear factor; < 0: not given
  double mu = -1.0;        ///< Coulomb coefficient; < 0: not given
  double v0_rel = 1e-2;    ///< smoothing slip velocity, relative to the process speed

  void add_to(CLI::App& app) {
    auto* stick = app.add_flag("--sticking", sticking, "Sticking friction on every tool (no slip)");
    auto* tresca = app.add_option("--friction-m", m,
                                  "Tresca friction on every tool: friction stress m k, k = sigma_eq / sqrt(3)")
                       ->check(CLI::Range(0.0, 1.0));
    auto* coulomb = app.add_option("--friction-mu", mu,
                                   "Coulomb friction on every tool: friction stress min(mu p_n, k), p_n the "
                                   "contact pressure")
                        ->check(CLI::NonNegativeNumber);
    stick->excludes(tresca);
    stick->excludes(coulomb);
    tresca->excludes(coulomb);
    app.add_option("--friction-v0", v0_rel,
                   "Tresca and Coulomb smoothing: slip velocity (relative to the process speed) below which "
                   "the friction stress falls off linearly")
        ->check(CLI::Range(1e-6, 1.0));
  }
  bool frictionless() const { return !sticking && m < 0 && mu < 0; }
  /// The law, with the smoothing scaled by the process speed V.
  AnyContactLaw law(double V) const {
    if (sticking) return Sticking{};
    if (m >= 0) return Tresca(m, v0_rel * V);
    if (mu >= 0) return Coulomb(mu, v0_rel * V);
    return Frictionless{};
  }
  std::string describe() const {
    if (sticking) return "sticking";
    if (m >= 0) return "Tresca m = " + std::to_string(m);
    if (mu >= 0) return "Coulomb mu = " + std::to_string(mu);
    return "frictionless";
  }
};

}  // namespace maxentflow::examples
