// One pass over an OSM XML file's bytes: node id order, and nodes listed
// after ways or relations (osm_xml_order.hpp).
#include "osm_xml_order.hpp"

#include <cpl_vsi.h>

#include <cctype>
#include <charconv>
#include <cstring>
#include <memory>
#include <string_view>
#include <vector>

namespace prep::detail {
namespace {

struct FileCloser {
  void operator()(VSILFILE* f) const { VSIFCloseL(f); }
};

bool name_ends(std::string_view tag, size_t n) {
  return tag.size() == n || tag[n] == ' ' || tag[n] == '\t' || tag[n] == '\n' || tag[n] == '\r' ||
         tag[n] == '/' || tag[n] == '>';
}

// The value of attribute `id` in the text of a start tag ("node id=..." up
// to its '>'); "" when it has none.
std::string_view id_of(std::string_view tag) {
  for (size_t at = tag.find("id="); at != std::string_view::npos; at = tag.find("id=", at + 3)) {
    if (at == 0 || !std::isspace(static_cast<unsigned char>(tag[at - 1]))) continue;  // uid=
    if (at + 3 >= tag.size()) return {};
    const char quote = tag[at + 3];
    if (quote != '"' && quote != '\'') return {};
    const size_t end = tag.find(quote, at + 4);
    if (end == std::string_view::npos) return {};
    return tag.substr(at + 4, end - at - 4);
  }
  return {};
}

// True when the first element of `text` (after a UTF-8 BOM, the XML
// declaration, comments and whitespace) is <osm>.
bool osm_root(std::string_view text) {
  size_t k = text.substr(0, 3) == "\xEF\xBB\xBF" ? 3 : 0;
  for (;;) {
    while (k < text.size() && std::isspace(static_cast<unsigned char>(text[k]))) ++k;
    if (k >= text.size() || text[k] != '<') return false;
    const std::string_view rest = text.substr(k + 1);
    if (rest.substr(0, 1) == "?" || rest.substr(0, 1) == "!") {
      const size_t end = text.find('>', k);
      if (end == std::string_view::npos) return false;
      k = end + 1;
      continue;
    }
    return rest.substr(0, 3) == "osm" && rest.size() > 3 && name_ends(rest, 3);
  }
}

}  // namespace

OsmXmlOrder scan_osm_xml(const std::string& path) {
  OsmXmlOrder out;
  std::unique_ptr<VSILFILE, FileCloser> f(VSIFOpenL(path.c_str(), "rb"));
  if (!f) return out;
  // A small first read decides whether this is OSM XML at all.
  std::vector<char> chunk(size_t(64) << 10);
  std::string buf;  // unprocessed text: starts at a '<' whose tag may be cut
  int64_t buf_offset = 0;
  bool first = true, seen_node = false;
  std::string earlier_kind, earlier_id;
  int64_t last_id = 0;
  for (;;) {
    const size_t got = VSIFReadL(chunk.data(), 1, chunk.size(), f.get());
    if (got == 0) break;
    buf.append(chunk.data(), got);
    if (first) {
      if (!osm_root(buf)) return out;
      first = false;
      chunk.resize(size_t(4) << 20);
    }
    size_t at = 0;
    for (;;) {
      const size_t lt = buf.find('<', at);
      if (lt == std::string::npos) {
        at = buf.size();
        break;
      }
      const size_t gt = buf.find('>', lt);
      if (gt == std::string::npos) {  // the tag goes on in the next chunk
        at = lt;
        break;
      }
      const std::string_view tag(buf.data() + lt + 1, gt - lt - 1);
      at = gt + 1;
      if (tag.compare(0, 4, "node") == 0 && name_ends(tag, 4)) {
        const std::string_view id = id_of(tag);
        int64_t value = 0;
        const auto [ptr, ec] = std::from_chars(id.data(), id.data() + id.size(), value);
        const bool numeric = ec == std::errc() && ptr == id.data() + id.size() && !id.empty();
        if (numeric) {
          if (seen_node && value <= last_id) out.node_ids_increase = false;
          last_id = value;
          seen_node = true;
        }
        if (!earlier_kind.empty() && out.late_node_offset < 0) {
          out.late_node_offset = buf_offset + int64_t(lt);
          out.late_node_id = std::string(id);
          out.earlier_kind = earlier_kind;
          out.earlier_id = earlier_id;
        }
      } else if (earlier_kind.empty() &&
                 ((tag.compare(0, 3, "way") == 0 && name_ends(tag, 3)) ||
                  (tag.compare(0, 8, "relation") == 0 && name_ends(tag, 8)))) {
        earlier_kind = tag[0] == 'w' ? "way" : "relation";
        earlier_id = std::string(id_of(tag));
      }
      // Both answers are known: the rest of the file cannot change them.
      if (!out.node_ids_increase && out.late_node_offset >= 0) {
        out.scanned = true;
        return out;
      }
    }
    buf.erase(0, at);
    buf_offset += int64_t(at);
  }
  out.scanned = !first;
  return out;
}

}  // namespace prep::detail
