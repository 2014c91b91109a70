#include "subslip/io/law_block.hpp"

namespace subslip::io {

namespace {

using law::OverstressForm;
using law::SubloadingFunction;

// A phase or contact law is complete (every key required, as in a contact scene); a per-family law
// is partial: each key it gives replaces the phase value, the others are inherited.

double read_number(const CheckedNode& node, std::string_view key, double inherited, bool partial,
                   const Range& range, const Unit& unit = Unit{dimension::none, {}, "1"}) {
  return partial ? node.get_quantity(key, inherited, unit, range)
                 : node.get_quantity(key, unit, range);
}

// Applies `read` to the block `key` of `node`: required for a complete law, optional (and then
// left as inherited) for a partial one.
template <class Read>
void read_block(const CheckedNode& node, std::string_view key, bool partial, Read&& read) {
  if (partial) {
    if (auto block = node.optional(key)) read(*block);
  } else {
    read(node.required(key));
  }
}

void parse_friction(const CheckedNode& node, law::FrictionCoefficientEvolution& f, bool partial,
                    const LawUnits& units) {
  node.allow_keys({"mu_s", "mu_k", "kappa", "xi"});
  f.mu_s = read_number(node, "mu_s", f.mu_s, partial, Range::positive());
  f.mu_k = read_number(node, "mu_k", f.mu_k, partial, Range::positive());
  f.kappa = read_number(node, "kappa", f.kappa, partial, Range::non_negative(), units.per_slip);
  f.xi = read_number(node, "xi", f.xi, partial, Range::non_negative(), units.per_time);
}

void parse_subloading(const CheckedNode& node, law::SubloadingEvolution& s, bool partial,
                      const LawUnits& units) {
  node.allow_keys({"function", "u_tilde"});
  if (auto f = node.optional("function")) {
    s.function = f->as_enum<SubloadingFunction>({{"cot", SubloadingFunction::cot},
                                                 {"neg_log", SubloadingFunction::neg_log},
                                                 {"reciprocal", SubloadingFunction::reciprocal}});
  }
  s.u_tilde = read_number(node, "u_tilde", s.u_tilde, partial, Range::positive(), units.per_slip);
}

void parse_overstress(const CheckedNode& node, law::Overstress& o, bool partial,
                      const LawUnits& units) {
  node.allow_keys({"form", "eta_v", "n", "r_hat"});
  const OverstressForm inherited_form = o.form;
  if (auto f = node.optional("form")) {
    o.form = f->as_enum<OverstressForm>({{"exponential", OverstressForm::exponential},
                                         {"power", OverstressForm::power},
                                         {"rate_independent", OverstressForm::rate_independent}});
  }
  if (o.form == OverstressForm::rate_independent) {
    // Silently ignoring them would let a reader believe they act.
    for (const char* unused : {"eta_v", "n", "r_hat"}) {
      if (auto v = node.optional(unused))
        v->fail("not used by the rate_independent form; remove it");
    }
    return;
  }
  // A rate-dependent form over an inherited rate-independent one has nothing to inherit.
  const bool own = !partial || inherited_form == OverstressForm::rate_independent;
  o.eta_v = read_number(node, "eta_v", o.eta_v, !own, Range::positive(), units.time_per_slip);
  o.n = read_number(node, "n", o.n, !own, Range::positive());
  o.r_hat = read_number(node, "r_hat", o.r_hat, !own, Range::greater_than(1.0));
}

}  // namespace

LawUnits contact_law_units(const Units& units) {
  return {units.unit(dimension::per_length), units.unit(dimension::per_time),
          units.unit(dimension::time_per_length)};
}

LawUnits crystal_law_units(const Units& units) {
  return {units.unit(dimension::none), units.unit(dimension::per_time),
          units.unit(dimension::time)};
}

law::LawParameters parse_law_block(const CheckedNode& node, const LawUnits& units,
                                   law::LawParameters base, bool partial) {
  node.allow_keys({"friction", "subloading", "overstress"});
  read_block(node, "friction", partial,
             [&](const CheckedNode& n) { parse_friction(n, base.friction, partial, units); });
  read_block(node, "subloading", partial,
             [&](const CheckedNode& n) { parse_subloading(n, base.subloading, partial, units); });
  read_block(node, "overstress", partial,
             [&](const CheckedNode& n) { parse_overstress(n, base.overstress, partial, units); });
  return base;
}

}  // namespace subslip::io
