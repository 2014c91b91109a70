#include "subslip/io/law_block.hpp"

#include <span>
#include <string>
#include <vector>

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

const law::LawBlockInfo& block_info(law::LawBlock block) {
  for (const auto& b : law::kLawBlocks) {
    if (b.block == block) return b;
  }
  return law::kLawBlocks.front();
}

// The keys a block takes: its choice, then its constants in table order.
void allow_block_keys(const CheckedNode& node, law::LawBlock block) {
  std::vector<std::string_view> keys;
  if (!block_info(block).choice_key.empty()) keys.push_back(block_info(block).choice_key);
  for (const auto& p : law::kLawParameters) {
    if (p.block == block) keys.push_back(p.name);
  }
  node.allow_keys(std::span<const std::string_view>(keys));
}

// Reads every constant of `block` (each inherited when partial and not given); reports every
// bad one.
void read_constants(const CheckedNode& node, law::LawBlock block, law::LawParameters& p,
                    bool partial, const LawUnits& units) {
  InputErrorList errors;
  for (const auto& c : law::kLawParameters) {
    if (c.block != block) continue;
    errors.attempt([&] {
      c.ref(p) = read_number(node, c.name, c.value(p), partial, law_constant_range(c.bound),
                             law_constant_unit(units, c.unit));
    });
  }
  errors.throw_if_any();
}

void parse_friction(const CheckedNode& node, law::LawParameters& p, bool partial,
                    const LawUnits& units) {
  allow_block_keys(node, law::LawBlock::friction);
  read_constants(node, law::LawBlock::friction, p, partial, units);
}

void parse_subloading(const CheckedNode& node, law::LawParameters& p, bool partial,
                      const LawUnits& units) {
  allow_block_keys(node, law::LawBlock::subloading);
  InputErrorList errors;
  errors.attempt([&] {
    if (auto f = node.optional("function")) {
      p.subloading.function =
          f->as_enum<SubloadingFunction>({{"cot", SubloadingFunction::cot},
                                          {"neg_log", SubloadingFunction::neg_log},
                                          {"reciprocal", SubloadingFunction::reciprocal}});
    }
  });
  errors.attempt([&] { read_constants(node, law::LawBlock::subloading, p, partial, units); });
  errors.throw_if_any();
}

void parse_overstress(const CheckedNode& node, law::LawParameters& p, bool partial,
                      const LawUnits& units) {
  allow_block_keys(node, law::LawBlock::overstress);
  const OverstressForm inherited_form = p.overstress.form;
  if (auto f = node.optional("form")) {
    p.overstress.form =
        f->as_enum<OverstressForm>({{"exponential", OverstressForm::exponential},
                                    {"power", OverstressForm::power},
                                    {"rate_independent", OverstressForm::rate_independent}});
  }
  if (p.overstress.form == OverstressForm::rate_independent) {
    // Silently ignoring them would let a reader believe they act.
    for (const auto& c : law::kLawParameters) {
      if (!c.rate_dependent_only) continue;
      if (auto v = node.optional(c.name))
        v->fail("not used by the rate_independent form; remove it");
    }
    return;
  }
  // A rate-dependent form over an inherited rate-independent one has nothing to inherit.
  const bool own = !partial || inherited_form == OverstressForm::rate_independent;
  read_constants(node, law::LawBlock::overstress, p, !own, units);
}

}  // namespace

const Unit& law_constant_unit(const LawUnits& units, law::ParameterUnit kind) {
  static const Unit one{dimension::none, {}, "1"};
  switch (kind) {
    case law::ParameterUnit::per_slip:
      return units.per_slip;
    case law::ParameterUnit::per_time:
      return units.per_time;
    case law::ParameterUnit::time_per_slip:
      return units.time_per_slip;
    case law::ParameterUnit::none:
      break;
  }
  return one;
}

Range law_constant_range(law::ParameterBound bound) {
  switch (bound) {
    case law::ParameterBound::non_negative:
      return Range::non_negative();
    case law::ParameterBound::above_one:
      return Range::greater_than(1.0);
    case law::ParameterBound::positive:
      break;
  }
  return Range::positive();
}

LawUnits contact_law_units(const Units& units) {
  return {units.unit(dimension::per_length), units.unit(dimension::per_time),
          units.unit(dimension::time_per_length)};
}

LawUnits crystal_law_units(const Units& units) {
  return {units.unit(dimension::none), units.unit(dimension::per_time),
          units.unit(dimension::time)};
}

std::string law_unit_name(law::ParameterUnit kind, bool crystal, const Units& units) {
  switch (kind) {
    case law::ParameterUnit::per_slip:
      return crystal ? std::string(kDimensionless) : units.per_length();
    case law::ParameterUnit::per_time:
      return units.per_time();
    case law::ParameterUnit::time_per_slip:
      return crystal ? units.time : units.time_per_length();
    case law::ParameterUnit::none:
      break;
  }
  return std::string(kDimensionless);
}

law::LawParameters parse_law_block(const CheckedNode& node, const LawUnits& units,
                                   law::LawParameters base, bool partial) {
  node.allow_keys({"friction", "subloading", "overstress"});
  InputErrorList errors;  // the three blocks are independent: every one is read
  errors.attempt([&] {
    read_block(node, "friction", partial,
               [&](const CheckedNode& n) { parse_friction(n, base, partial, units); });
  });
  errors.attempt([&] {
    read_block(node, "subloading", partial,
               [&](const CheckedNode& n) { parse_subloading(n, base, partial, units); });
  });
  errors.attempt([&] {
    read_block(node, "overstress", partial,
               [&](const CheckedNode& n) { parse_overstress(n, base, partial, units); });
  });
  errors.throw_if_any();
  return base;
}

}  // namespace subslip::io
