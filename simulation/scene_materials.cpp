// The scene file's [[materials]], [default_contact_law] and [[contact_laws]] (docs/scene-file.md);
// the keys of a material and of a contact law are read from their tables (scene_keys.hpp).
#include <array>

#include "simulation/scene_keys.hpp"
#include "simulation/scene_parser.hpp"

namespace rubble::scene_detail {

namespace {

/// " (expected one of: ...)" after an unknown material name.
std::string known_materials(const SceneDraft& draft) {
  if (draft.material_ids.empty()) return " (no [[materials]] are defined)";
  std::string list = " (expected one of:";
  for (const Material& m : draft.scene.model.materials) list += " \"" + m.name + "\"";
  return list + ")";
}

ContactLaw parse_law(const TableReader& entry) {
  ContactLaw law;
  read_section_keys(entry, contact_law_keys(), law);
  return law;
}

/// The material pair of a [[contact_laws]] entry, as material ids.
std::array<int, 2> law_materials(const SceneDraft& draft, const TableReader& entry) {
  const toml::node* node = entry.get("materials");
  if (!node) entry.missing("materials", "a pair of material names, e.g. [\"rock\", \"rock\"]");
  const auto* array = node->as_array();
  if (!array || array->size() != 2 || !array->get(0)->is_string() || !array->get(1)->is_string()) {
    entry.fail(node, entry.key_path("materials"),
               "expected a pair of material names, e.g. [\"rock\", \"rock\"], got " + describe_node(*node));
  }
  std::array<int, 2> ids{};
  for (int k = 0; k < 2; ++k) {
    const std::string name(array->get(static_cast<std::size_t>(k))->as_string()->get());
    const auto it = draft.material_ids.find(name);
    if (it == draft.material_ids.end()) {
      entry.fail(node, entry.key_path("materials"), "unknown material \"" + name + "\"" + known_materials(draft));
    }
    ids[static_cast<std::size_t>(k)] = it->second;
  }
  return ids;
}

}  // namespace

void parse_materials(SceneDraft& draft) {
  for (const TableReader& entry : draft.root.tables("materials")) {
    entry.allow_only(key_names(material_keys()), "in [[materials]]");
    MaterialEntry material{.material = {}, .defined = &draft.material_ids};
    read_section_keys(entry, material_keys(), material);
    draft.material_ids[material.material.name] = static_cast<int>(draft.scene.model.materials.size());
    draft.scene.model.materials.push_back(std::move(material.material));
  }
}

int material_of(const SceneDraft& draft, const TableReader& entry) {
  const auto name = entry.optional_string("material");
  if (!name) {
    if (draft.scene.model.materials.size() == 1) return 0;
    if (draft.scene.model.materials.empty()) {
      entry.fail_table("no materials defined: expected a [[materials]] entry with name and density");
    }
    entry.missing("material", "the name of a [[materials]] entry (required when there are several)");
  }
  const auto it = draft.material_ids.find(*name);
  if (it == draft.material_ids.end()) {
    entry.fail_key("material", "unknown material \"" + *name + "\"" + known_materials(draft));
  }
  return it->second;
}

void parse_contact_laws(SceneDraft& draft) {
  const int n = static_cast<int>(draft.scene.model.materials.size());
  if (const auto fallback = draft.root.optional_table("default_contact_law")) {
    fallback->allow_only(key_names(contact_law_keys()), "in [default_contact_law]");
    draft.default_law = parse_law(*fallback);
  }
  draft.scene.model.contact_laws.reset(n, draft.default_law.value_or(ContactLaw{}));
  draft.law_defined.assign(static_cast<std::size_t>(n) * static_cast<std::size_t>(n), false);
  for (const TableReader& entry : draft.root.tables("contact_laws")) {
    std::vector<std::string_view> allowed = {"materials"};
    for (const std::string_view key : key_names(contact_law_keys())) allowed.push_back(key);
    entry.allow_only(allowed, "in [[contact_laws]]");
    const auto [a, b] = law_materials(draft, entry);
    if (draft.law_defined[draft.scene.model.contact_laws.index(a, b)]) {
      entry.fail(entry.get("materials"), entry.key_path("materials"),
                 "the contact law of this pair is defined twice (expected one entry per pair)");
    }
    draft.scene.model.contact_laws.set(a, b, parse_law(entry));
    draft.law_defined[draft.scene.model.contact_laws.index(a, b)] = true;
    draft.law_defined[draft.scene.model.contact_laws.index(b, a)] = true;
  }
}

}  // namespace rubble::scene_detail
