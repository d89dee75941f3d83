// StepContext: what one attempt at a time interval knows about that interval.
//
// A step of the scene's dt is attempted once; if the attempt fails it is retried as two attempts
// of half the interval (engine/simulation.cpp, Simulation::advance_or_split), and so on. Every
// number that depends on the interval (dt, the integrator's weights s, s_c, the contact memory's
// weight) is computed here, from the interval and the attempt's scheme, and handed down to the
// stages and the potential terms. Nothing else keeps a copy of dt or of anything derived from it,
// so an attempt over half the interval is exactly a step of a scene whose dt is half as large.
#pragma once

#include "engine/integrator.hpp"

namespace nexdyn {

struct StepContext {
  double t_start = 0.0;  // [s] the state's time
  double t_end = 0.0;    // [s] the time the attempt advances to
  // [s] the length of the interval: the scene's dt, or half the parent attempt's interval (not
  // recomputed as t_end - t_start, which rounds differently when t_start is large)
  double dt = 0.0;
  int level = 0;         // 0: the scene's dt; k: the k-th halving of it
  // The scheme of the attempt: the scene's, or implicit Euler (a first step that starts in
  // contact, or an attempt the energy guard retakes).
  const IntegratorParams* scheme = nullptr;
  // The weights of the incremental potential for this dt (engine/integrator.hpp):
  double potential_scale = 1.0;       // s   (elastic energy, gravity, joints)
  double contact_scale = 1.0;         // s_c (barrier and friction)
  double contact_memory_scale = 0.0;  // of the start-of-step contact force in x_tilde
  bool inertia = true;                // false for "static"
};

inline StepContext make_step_context(const IntegratorParams& scheme, double t_start, double dt,
                                     double t_end, int level) {
  StepContext ctx;
  ctx.t_start = t_start;
  ctx.t_end = t_end;
  ctx.dt = dt;
  ctx.level = level;
  ctx.scheme = &scheme;
  ctx.potential_scale = scheme.potential_scale(ctx.dt);
  ctx.contact_scale = scheme.contact_scale(ctx.dt);
  ctx.contact_memory_scale = scheme.contact_memory_scale(ctx.dt);
  ctx.inertia = !scheme.is_static;
  return ctx;
}

// A context that carries only the potential's weights, for code that drives the potential without
// a time step (tests, benchmarks).
inline StepContext weights_context(double potential_scale, double contact_scale, bool inertia) {
  StepContext ctx;
  ctx.potential_scale = potential_scale;
  ctx.contact_scale = contact_scale;
  ctx.inertia = inertia;
  return ctx;
}

}  // namespace nexdyn
