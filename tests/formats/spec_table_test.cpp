// formats/SPEC.md must agree with decal/format.hpp: the blob catalogue table
// row for row, the header and blob-table field tables field for field, and
// the record sizes. The tables are parsed from the Markdown itself.
#include <gtest/gtest.h>

#include <cstring>
#include <fstream>
#include <map>
#include <sstream>

#include "decal/format.hpp"

// One test binary holds several files (a unity build): each keeps its
// names in a namespace of its own.
namespace formats_spec_table {

namespace {

using Row = std::vector<std::string>;

std::string trim(std::string s) {
  const auto a = s.find_first_not_of(" \t`");
  const auto b = s.find_last_not_of(" \t`");
  return a == std::string::npos ? "" : s.substr(a, b - a + 1);
}

std::string spec_text() {
  std::ifstream in(std::string(DECALPREP_SOURCE_DIR) + "/formats/SPEC.md");
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// The first Markdown table under the heading line `heading` (exact match),
// before the next heading: header row first, separator row dropped.
std::vector<Row> table_under(const std::string& text, const std::string& heading) {
  std::istringstream in(text);
  std::string line;
  bool in_section = false;
  std::vector<Row> rows;
  while (std::getline(in, line)) {
    if (line.rfind("#", 0) == 0) {
      if (in_section) break;
      in_section = line == heading;
      continue;
    }
    if (!in_section) continue;
    if (line.rfind("|", 0) != 0) {
      if (!rows.empty()) break;  // the table ended
      continue;
    }
    Row row;
    std::string cell;
    std::istringstream cells(line.substr(1));
    while (std::getline(cells, cell, '|')) row.push_back(trim(cell));
    if (!row.empty() && row[0].find("---") != std::string::npos) continue;
    if (!row.empty() && row[0].rfind(":--", 0) == 0) continue;
    if (!row.empty() && row[0].find("--:") != std::string::npos) continue;
    rows.push_back(row);
  }
  return rows;
}

size_t column(const Row& header, const std::string& name) {
  for (size_t i = 0; i < header.size(); ++i)
    if (header[i] == name) return i;
  ADD_FAILURE() << "no column '" << name << "'";
  return 0;
}

TEST(Spec, BlobCatalogueTableListsExactlyTheHeaderCatalogue) {
  const auto rows = table_under(spec_text(), "## Blob catalogue");
  ASSERT_GE(rows.size(), 2u) << "no table under '## Blob catalogue' in SPEC.md";
  const Row& h = rows[0];
  const size_t c_id = column(h, "id"), c_name = column(h, "name"),
               c_type = column(h, "element type"), c_stride = column(h, "stride");
  ASSERT_EQ(rows.size() - 1, std::size(decal::kBlobCatalogue))
      << "row count differs from kBlobCatalogue";
  for (size_t i = 0; i < std::size(decal::kBlobCatalogue); ++i) {
    const auto& b = decal::kBlobCatalogue[i];
    const Row& r = rows[i + 1];
    SCOPED_TRACE("SPEC row " + std::to_string(i + 1) + ": " + r.at(c_name));
    EXPECT_EQ(r.at(c_id), std::to_string(static_cast<uint32_t>(b.id)));
    EXPECT_EQ(r.at(c_name), b.name);
    EXPECT_EQ(r.at(c_type), decal::element_type_name(b.type));
    EXPECT_EQ(r.at(c_stride), std::to_string(b.stride));
  }
}

// Checks a field table (offset | size | type | field | ...) against
// (field name -> offset, size) taken from the struct with offsetof/sizeof.
void expect_fields(const std::string& heading,
                   const std::map<std::string, std::pair<size_t, size_t>>& fields,
                   size_t struct_size) {
  const auto rows = table_under(spec_text(), heading);
  ASSERT_GE(rows.size(), 2u) << heading;
  const size_t c_off = column(rows[0], "offset"), c_size = column(rows[0], "size"),
               c_field = column(rows[0], "field");
  std::map<std::string, bool> seen;
  size_t covered = 0;
  for (size_t i = 1; i < rows.size(); ++i) {
    const std::string name = rows[i].at(c_field);
    auto it = fields.find(name);
    ASSERT_NE(it, fields.end()) << heading << ": SPEC documents unknown field " << name;
    EXPECT_EQ(rows[i].at(c_off), std::to_string(it->second.first)) << name;
    EXPECT_EQ(rows[i].at(c_size), std::to_string(it->second.second)) << name;
    seen[name] = true;
    covered += it->second.second;
  }
  for (const auto& [name, _] : fields)
    EXPECT_TRUE(seen[name]) << heading << ": SPEC misses field " << name;
  EXPECT_EQ(covered, struct_size) << heading;
}

#define FIELD(S, f)                \
  {                                \
#f, {                          \
      offsetof(S, f), sizeof(S::f) \
    }                              \
  }

TEST(Spec, FileHeaderTableMatchesTheStruct) {
  using H = decal::FileHeader;
  expect_fields("## File header",
                {FIELD(H, magic), FIELD(H, version_major), FIELD(H, version_minor), FIELD(H, flags),
                 FIELD(H, header_size), FIELD(H, blob_entry_size), FIELD(H, blob_count),
                 FIELD(H, reserved0), FIELD(H, file_size), FIELD(H, table_offset),
                 FIELD(H, table_checksum), FIELD(H, metadata_offset), FIELD(H, metadata_size),
                 FIELD(H, metadata_checksum), FIELD(H, reserved1), FIELD(H, header_checksum)},
                sizeof(H));
}

TEST(Spec, BlobTableEntryTableMatchesTheStruct) {
  using E = decal::BlobTableEntry;
  expect_fields("## Blob table",
                {FIELD(E, id), FIELD(E, element_type), FIELD(E, stride), FIELD(E, codec),
                 FIELD(E, count), FIELD(E, offset), FIELD(E, stored_size), FIELD(E, raw_size),
                 FIELD(E, checksum), FIELD(E, name), FIELD(E, reserved)},
                sizeof(E));
}

TEST(Spec, MagicTableMatchesTheMagicBytes) {
  const auto rows = table_under(spec_text(), "## Magic number");
  ASSERT_GE(rows.size(), 2u);
  ASSERT_EQ(rows[1].size(), 9u);
  for (size_t i = 0; i < 8; ++i) {
    char hex[8];
    std::snprintf(hex, sizeof hex, "0x%02X", decal::kMagic[i]);
    EXPECT_EQ(rows[1][i + 1], hex) << "byte " << i;
  }
}

TEST(Spec, RecordHeadingsGiveTheStructSizes) {
  const std::string text = spec_text();
  const std::pair<const char*, size_t> records[] = {
      {"### LineProps (", sizeof(decal::LineProps)},
      {"### LineCorner (", sizeof(decal::LineCorner)},
      {"### PolyProps (", sizeof(decal::PolyProps)},
      {"### LodPoint (", sizeof(decal::LodPoint)},
      {"### LodSegment (", sizeof(decal::LodSegment)}};
  for (const auto& [heading, size] : records) {
    const auto at = text.find(heading);
    ASSERT_NE(at, std::string::npos) << heading;
    EXPECT_EQ(text.compare(at + std::strlen(heading), std::to_string(size).size() + 6,
                           std::to_string(size) + " bytes"),
              0)
        << heading;
  }
}

}  // namespace

}  // namespace formats_spec_table
