#include "pipeline/interrogation_json.h"

namespace s2m::pipeline {

nlohmann::json InterrogationJson(const CurveInterrogation& q, int dimension) {
  nlohmann::json inter = {{"length", q.length},
                          {"comb_scale", q.comb_scale},
                          {"max_abs_kappa", q.max_abs_kappa},
                          {"zeta", q.zeta},
                          {"dkappa_ds_squared", q.dkappa_ds_squared},
                          {"kappa_squared", q.kappa_squared},
                          {"curvature_extrema", q.curvature_extrema},
                          {"inflections", q.inflections},
                          {"max_g1", q.max_g1},
                          {"max_g2", q.max_g2}};
  nlohmann::json junctions = nlohmann::json::array();
  for (const JunctionJump& j : q.junctions)
    junctions.push_back({{"u", j.u}, {"s", j.s}, {"g1", j.g1}, {"g2", j.g2}, {"g3", j.g3}});
  inter["junctions"] = junctions;
  nlohmann::json s = nlohmann::json::array(), u = s, kappa = s, dk = s, tau = s, point = s, tip = s;
  for (const CurvatureSample& c : q.samples) {
    s.push_back(c.s);
    u.push_back(c.u);
    kappa.push_back(c.kappa);
    dk.push_back(c.dkappa_ds);
    tau.push_back(c.torsion);
    const Eigen::VectorXd p = c.point.head(dimension), t = c.comb_tip.head(dimension);
    point.push_back(std::vector<double>(p.data(), p.data() + p.size()));
    tip.push_back(std::vector<double>(t.data(), t.data() + t.size()));
  }
  inter["samples"] = {{"s", s},          {"u", u},         {"kappa", kappa},
                      {"dkappa_ds", dk}, {"point", point}, {"comb_tip", tip}};
  if (dimension == 3) inter["samples"]["torsion"] = tau;
  return inter;
}

}  // namespace s2m::pipeline
