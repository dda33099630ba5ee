// Scene specs from TOML, JSON and `key=value` settings, and back to JSON (see spec_io.h).
#include "activefoam/spec_io.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cstring>
#include <fstream>
#include <functional>
#include <iostream>
#include <iterator>
#include <limits>
#include <optional>
#include <set>
#include <sstream>

#include <toml++/toml.h>

#include "activefoam/spec_reads.h"

namespace activefoam {
namespace {

// Errors are one line each: parser messages may quote input with newlines.
std::string oneLine(std::string_view s) {
  std::string out;
  for (char c : s) out += (c == '\n' || c == '\r' || c == '\t') ? ' ' : c;
  return out;
}

std::string join(std::string_view prefix, std::string_view key) {
  return prefix.empty() ? std::string(key) : std::string(prefix) + "." + std::string(key);
}

// "prepare.<key>": a key of the [prepare] table, whose tables are the spec's (setField takes it).
constexpr std::string_view kPrepare = "prepare";
bool isPrepareKey(std::string_view key) {
  return key.size() > kPrepare.size() && key.compare(0, kPrepare.size(), kPrepare) == 0 &&
         key[kPrepare.size()] == '.';
}

// A table of keys: "cells", "numerics", "scene", "accuracy", "observe" (every key "<group>.<leaf>"
// lives in one), and "prepare" with those within it.
bool isGroup(std::string_view key) {
  if (key == kPrepare) return true;
  if (isPrepareKey(key)) key.remove_prefix(kPrepare.size() + 1);
  for (const SpecField& f : specFields())
    if (f.key.size() > key.size() && f.key.compare(0, key.size(), key) == 0 &&
        f.key[key.size()] == '.')
      return true;
  return false;
}

std::string expected(const SpecField& f) {
  if (f.type == FieldType::Boolean) return f.range();
  if (f.type == FieldType::Choice || !f.choices.empty()) return f.range();
  return f.type == FieldType::Integer ? "an integer" : "a number";
}

SpecError unknownTable(const std::string& key) {
  std::string msg = "unknown table '" + key + "'";
  for (std::string_view g : {"cells", "numerics", "scene", "accuracy", "observe", "prepare"})
    if (editDistance(g, key) <= 2) msg += " (did you mean [" + std::string(g) + "]?)";
  msg += "; the tables are [cells], [numerics], [scene], [accuracy], [observe], [prepare]";
  return {key, msg};
}

bool isSceneKey(std::string_view key) {
  return key == "scene" || key == "scene.kind";
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.front()))) s.remove_prefix(1);
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.remove_suffix(1);
  return s;
}

// Walks a document (TOML or JSON) and feeds its leaves to setField. `Doc` supplies, for one
// node, what kind it is and its value.
class Walker {
 public:
  Walker(SceneSpec& spec, SpecParseResult& result, bool record = false)
      : spec_(spec), result_(result), record_(record) {}

  void leaf(const std::string& key, const SpecValue& value) {
    if (isPrepareKey(key)) {
      // `"cells.xi" = …` in [prepare] and `xi = …` in [prepare.cells] are one key.
      if (std::find(result_.keys.begin(), result_.keys.end(), key) != result_.keys.end())
        error(key, "given twice in [prepare] (as a dotted key and in a table): give it once");
      else if (auto e = setField(spec_, key, value))
        result_.errors.push_back(*e);
      else
        result_.keys.push_back(key);
      return;
    }
    const SpecField* f = findField(key);
    // A record's labels only name the values it holds (a retired preset's among them).
    if (f && record_ && f->label) return;
    if (!f) {
      if (auto retired = setRetiredField(spec_, key, value)) {
        if (*retired) result_.errors.push_back(**retired);
        return;
      }
      if (isGroup(key))
        error(key, "expected a table, got " + describe(value));
      else
        error(key, "unknown key '" + key + "'" + suggestion(key));
      return;
    }
    if (isSceneKey(key)) {
      if (result_.scene_given) {
        error(key, "the scene is given twice (scene = \"...\" and kind in [scene])");
        return;
      }
      result_.scene_given = true;
    }
    if (auto e = setField(spec_, key, value))
      result_.errors.push_back(*e);
    else
      result_.keys.push_back(key);
  }

  void null(const std::string& key) {
    const SpecField* f = findField(key);
    if (isPrepareKey(key)) {  // the run's value, as without it
      if (auto e = clearField(spec_, key)) result_.errors.push_back(*e);
    } else if (!f) {
      error(key, "unknown key '" + key + "'" + suggestion(key));
    } else if (!f->optional) {
      error(key, "expected " + expected(*f) + ", got null");
    } else if (auto e = clearField(spec_, key)) {
      result_.errors.push_back(*e);
    } else {
      result_.keys.push_back(key);
    }
  }

  // A node that is neither a table nor a scalar (array, date, ...): `what` names it.
  void other(const std::string& key, const std::string& what) {
    if (isPrepareKey(key) && !isGroup(key))
      error(key, "expected a number, string or boolean, got " + what);
    else if (const SpecField* f = findField(key))
      error(key, "expected " + expected(*f) + ", got " + what);
    else if (isGroup(key))
      error(key, "expected a table, got " + what);
    else
      error(key, "unknown key '" + key + "'" + suggestion(key));
  }

  // Returns whether the table's entries should be walked.
  bool table(const std::string& key) {
    if (isGroup(key)) return true;
    if (const SpecField* f = findField(key))
      error(key, "expected " + expected(*f) + ", got a table");
    else if (key.find('.') == std::string::npos)
      result_.errors.push_back(unknownTable(key));
    else
      error(key, "unknown table '" + key + "'" + suggestion(key));
    return false;
  }

 private:
  static std::string describe(const SpecValue& v) {
    if (std::holds_alternative<std::string>(v)) return "'" + std::get<std::string>(v) + "'";
    if (std::holds_alternative<bool>(v)) return std::get<bool>(v) ? "true" : "false";
    if (std::holds_alternative<std::int64_t>(v)) return std::to_string(std::get<std::int64_t>(v));
    return formatNumber(std::get<double>(v));
  }
  static std::string suggestion(const std::string& key) {
    const std::string s = suggestKey(key);
    return s.empty() ? "" : " (did you mean '" + s + "'?)";
  }
  void error(const std::string& key, std::string msg) {
    result_.errors.push_back({key, oneLine(msg)});
  }

  SceneSpec& spec_;
  SpecParseResult& result_;
  bool record_;
};

// ---- TOML --------------------------------------------------------------------------------------

// A spec may write `scene = "fusion"` and a [scene] table in one document, which TOML forbids
// (a key redefined as a table). That form is accepted: when the top level assigns `scene`, a
// `[scene]` header is read as this name and walked as the scene table. Lines keep their numbers.
constexpr std::string_view kSceneTableAlias = "__scene_table__";

// Plain string checks (GCC 12's <regex> trips -Wmaybe-uninitialized at -O3).
std::string_view skipSpace(std::string_view l) {
  const std::size_t i = l.find_first_not_of(" \t\r");
  return i == std::string_view::npos ? std::string_view{} : l.substr(i);
}

// `scene =` (and not e.g. `scenery =`) at the start of a line.
bool assignsScene(std::string_view l) {
  l = skipSpace(l);
  if (l.substr(0, 5) != "scene") return false;
  l = skipSpace(l.substr(5));
  return !l.empty() && l.front() == '=';
}

// `[scene]` with optional spaces and a trailing comment: returns the comment (possibly empty).
std::optional<std::string> sceneHeaderComment(std::string_view l) {
  l = skipSpace(l);
  if (l.empty() || l.front() != '[') return std::nullopt;
  l = skipSpace(l.substr(1));
  if (l.substr(0, 5) != "scene") return std::nullopt;
  l = skipSpace(l.substr(5));
  if (l.empty() || l.front() != ']') return std::nullopt;
  l = skipSpace(l.substr(1));
  if (!l.empty() && l.front() != '#') return std::nullopt;
  return std::string(l);
}

std::string liftSceneTable(std::string_view text) {
  std::vector<std::string> lines;
  std::size_t start = 0;
  while (start <= text.size()) {
    const std::size_t end = std::min(text.find('\n', start), text.size());
    lines.emplace_back(text.substr(start, end - start));
    start = end + 1;
  }
  bool top = true, scene_key = false;
  for (const std::string& l : lines) {
    const std::string_view t = skipSpace(l);
    if (!t.empty() && t.front() == '[') top = false;
    if (top && assignsScene(l)) scene_key = true;
  }
  if (!scene_key) return std::string(text);
  std::string out;
  for (std::size_t i = 0; i < lines.size(); ++i) {
    if (const auto comment = sceneHeaderComment(lines[i]))
      out += "[" + std::string(kSceneTableAlias) + "] " + *comment;
    else
      out += lines[i];
    if (i + 1 < lines.size()) out += '\n';
  }
  return out;
}

void walkToml(const toml::table& table, const std::string& prefix, Walker& w) {
  for (auto&& [k, node] : table) {
    const std::string key =
        prefix.empty() && k.str() == kSceneTableAlias ? "scene" : join(prefix, k.str());
    switch (node.type()) {
      case toml::node_type::table:
        if (w.table(key)) walkToml(*node.as_table(), key, w);
        break;
      case toml::node_type::string:
        w.leaf(key, std::string(node.as_string()->get()));
        break;
      case toml::node_type::integer:
        w.leaf(key, static_cast<std::int64_t>(node.as_integer()->get()));
        break;
      case toml::node_type::floating_point:
        w.leaf(key, node.as_floating_point()->get());
        break;
      case toml::node_type::boolean:
        w.leaf(key, node.as_boolean()->get());
        break;
      case toml::node_type::array:
        w.other(key, "an array");
        break;
      default:
        w.other(key, "a date/time");
        break;
    }
  }
}

// ---- JSON --------------------------------------------------------------------------------------

void walkJson(const nlohmann::json& obj, const std::string& prefix, Walker& w) {
  for (auto it = obj.begin(); it != obj.end(); ++it) {
    const std::string key = join(prefix, it.key());
    const nlohmann::json& v = it.value();
    if (v.is_object()) {
      if (w.table(key)) walkJson(v, key, w);
    } else if (v.is_string()) {
      w.leaf(key, v.get<std::string>());
    } else if (v.is_number_unsigned()) {
      const auto u = v.get<std::uint64_t>();
      if (u <= static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max()))
        w.leaf(key, static_cast<std::int64_t>(u));
      else
        w.leaf(key, static_cast<double>(u));
    } else if (v.is_number_integer()) {
      w.leaf(key, v.get<std::int64_t>());
    } else if (v.is_number_float()) {
      w.leaf(key, v.get<double>());
    } else if (v.is_boolean()) {
      w.leaf(key, v.get<bool>());
    } else if (v.is_null()) {
      w.null(key);
    } else {
      w.other(key, "an array");
    }
  }
}

SpecParseResult finish(SceneSpec spec, SpecParseResult result, const SpecParseOptions& options) {
  if (options.require_scene && !result.scene_given && result.errors.empty()) {
    result.errors.push_back({"scene", "missing: the spec must name its scene, " +
                                          findField("scene")->range() +
                                          " (scene = \"...\", or kind = \"...\" in [scene])"});
  }
  if (result.errors.empty()) result.spec = std::move(spec);
  return result;
}

std::string sourceName(const SpecParseOptions& options, const char* fallback) {
  return options.source.empty() ? fallback : options.source;
}

// Value text of a --set, read by the key's type.
SpecValue settingValue(const SpecField* f, std::string_view text) {
  text = trim(text);
  const bool quoted = text.size() >= 2 && (text.front() == '"' || text.front() == '\'') &&
                      text.back() == text.front();
  if (quoted) return std::string(text.substr(1, text.size() - 2));
  if (f && f->type == FieldType::Choice) return std::string(text);
  std::string_view num = text;
  if (!num.empty() && num.front() == '+') num.remove_prefix(1);
  std::int64_t i = 0;
  if (auto [p, ec] = std::from_chars(num.data(), num.data() + num.size(), i);
      ec == std::errc() && p == num.data() + num.size() && !num.empty())
    return i;
  double d = 0;
  if (auto [p, ec] = std::from_chars(num.data(), num.data() + num.size(), d);
      ec == std::errc() && p == num.data() + num.size() && !num.empty())
    return d;
  if (text == "true") return true;
  if (text == "false") return false;
  return std::string(text);
}

}  // namespace

SpecFormat sniffSpecFormat(std::string_view text) {
  for (char c : text) {
    if (std::isspace(static_cast<unsigned char>(c))) continue;
    return c == '{' ? SpecFormat::Json : SpecFormat::Toml;
  }
  return SpecFormat::Toml;
}

SpecParseResult parseSpecJson(const nlohmann::json& doc, const SceneSpec& base,
                              const SpecParseOptions& options) {
  SpecParseResult result;
  SceneSpec spec = base;
  if (!doc.is_object()) {
    result.errors.push_back(
        {sourceName(options, "<json>"),
         std::string("expected a JSON object at the top level, got ") + doc.type_name()});
    return result;
  }
  Walker w(spec, result, options.record);
  walkJson(doc, "", w);
  return finish(std::move(spec), std::move(result), options);
}

namespace {

// The dotted key whose value is the first occurrence of `literal` outside a string in a JSON
// text ("" when not found): a light scan keeping the stack of object keys.
std::string jsonKeyBefore(std::string_view text, const std::string& literal) {
  std::vector<std::string> keys;  // one per open object ("" until its first key)
  std::string last_string;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (c == '"') {
      std::string str;
      for (++i; i < text.size() && text[i] != '"'; ++i) {
        if (text[i] == '\\' && i + 1 < text.size()) ++i;
        str += text[i];
      }
      last_string = str;
      continue;
    }
    if (c == '{') {
      keys.emplace_back();
    } else if (c == '}') {
      if (!keys.empty()) keys.pop_back();
    } else if (c == ':') {
      if (!keys.empty()) keys.back() = last_string;
    } else if (text.compare(i, literal.size(), literal) == 0) {
      std::string dotted;
      for (const std::string& k : keys) dotted += (dotted.empty() ? "" : ".") + k;
      return dotted;
    }
  }
  return "";
}

// The dotted keys that a JSON text gives twice in one object: the JSON reader keeps the last
// value without a word, so `"duration_s": 1, "duration_s": 2` ran for 2 s (tests/adversarial).
// The one repeat allowed is TOML's form `scene = "doublet"` with a `[scene]` table: a top-level
// "scene" string beside a "scene" object (kept here, merged by `mergeScene`).
struct DuplicateJsonKeys {
  struct Frame {
    bool object = false;
    std::set<std::string> keys;
    std::string current;
  };
  std::vector<Frame> frames;
  std::vector<std::string> found;
  int scenes = 0;  // top-level "scene" keys
  std::optional<std::string> scene_name;
  std::optional<nlohmann::json> scene_table;

  bool operator()(int, nlohmann::json::parse_event_t event, nlohmann::json& parsed) {
    using E = nlohmann::json::parse_event_t;
    const bool top_scene = frames.size() == 1 && frames[0].current == "scene";
    if (event == E::object_start || event == E::array_start) {
      frames.push_back({event == E::object_start, {}, {}});
    } else if (event == E::object_end || event == E::array_end) {
      if (!frames.empty()) frames.pop_back();
      if (frames.size() == 1 && frames[0].current == "scene" && parsed.is_object())
        scene_table = parsed;
    } else if (event == E::value && top_scene && parsed.is_string()) {
      scene_name = parsed.get<std::string>();
    } else if (event == E::key && !frames.empty()) {
      Frame& f = frames.back();
      f.current = parsed.get<std::string>();
      if (frames.size() == 1 && f.current == "scene") ++scenes;
      if (!f.keys.insert(f.current).second) {
        if (frames.size() == 1 && f.current == "scene") return true;  // judged by mergeScene
        std::string dotted;
        for (const Frame& g : frames)
          if (g.object) dotted = join(dotted, g.current);
        if (std::find(found.begin(), found.end(), dotted) == found.end()) found.push_back(dotted);
      }
    }
    return true;
  }

  // `"scene": NAME` and `"scene": {...}` together: the table with "kind" NAME, whichever came
  // last. False (and an error in `found`) when the two disagree or are not one of each.
  bool mergeScene(nlohmann::json& doc) {
    if (scenes < 2) return true;
    if (scenes > 2 || !scene_name || !scene_table) {
      found.push_back("scene");
      return false;
    }
    nlohmann::json table = *scene_table;
    if (table.contains("kind") && table["kind"] != *scene_name) {
      disagreement = true;
      return false;
    }
    table["kind"] = *scene_name;
    doc["scene"] = std::move(table);
    return true;
  }
  bool disagreement = false;
};

// The dotted key that line `line` (1-based) of a TOML text assigns ("" when it assigns none),
// from the table headers above it: toml++ names only the line and column of a value it cannot
// read (1e400, an integer beyond 64 bits), and the user looks for the key.
std::string tomlKeyAt(std::string_view text, std::size_t line) {
  std::string table;
  std::size_t start = 0;
  for (std::size_t n = 1; start <= text.size(); ++n) {
    const std::size_t end = std::min(text.find('\n', start), text.size());
    std::string_view l = skipSpace(text.substr(start, end - start));
    if (n == line) {
      std::string key;
      std::size_t i = 0;
      for (; i < l.size(); ++i) {
        const char c = l[i];
        if (std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.')
          key += c;
        else if (c != ' ' && c != '\t')
          break;
      }
      if (key.empty() || i >= l.size() || l[i] != '=') return "";
      return join(table, key);
    }
    if (!l.empty() && l.front() == '[') {
      const std::size_t open = l.find_first_not_of("[ \t"), close = l.find(']');
      if (open != std::string_view::npos && close != std::string_view::npos && close > open) {
        table = std::string(l.substr(open, close - open));
        while (!table.empty() && (table.back() == ' ' || table.back() == '\t')) table.pop_back();
      }
    }
    start = end + 1;
  }
  return "";
}

}  // namespace

SpecParseResult parseSpecText(std::string_view text, SpecFormat format, const SceneSpec& base,
                              const SpecParseOptions& options) {
  if (format == SpecFormat::Auto) {
    format = sniffSpecFormat(text);
    // A TOML text may start with '[' (a table header) and so may a JSON array: one that is JSON
    // gets JSON's error (not an object), not TOML's "expected bare key, saw '{'".
    const std::size_t first = text.find_first_not_of(" \t\r\n");
    if (format == SpecFormat::Toml && first != std::string_view::npos && text[first] == '[' &&
        nlohmann::json::accept(text, /*ignore_comments=*/true))
      format = SpecFormat::Json;
  }
  if (format == SpecFormat::Json) {
    nlohmann::json doc;
    DuplicateJsonKeys duplicates;
    try {
      doc = nlohmann::json::parse(text, std::ref(duplicates), /*allow_exceptions=*/true,
                                  /*ignore_comments=*/true);
    } catch (const nlohmann::json::parse_error& e) {
      std::string what = e.what();
      // "[json.exception.parse_error.101] parse error at line 2, column 3: ..."
      if (const auto p = what.find("] "); p != std::string::npos) what.erase(0, p + 2);
      SpecParseResult r;
      r.errors.push_back({sourceName(options, "<json>"), oneLine("JSON " + what)});
      return r;
    } catch (const nlohmann::json::exception& e) {
      // A number beyond double's range (1e400): "[json.exception.out_of_range.406] number
      // overflow parsing '1e400'" — an error of the spec naming its key, not an engine crash.
      std::string what = e.what();
      if (const auto p = what.find("] "); p != std::string::npos) what.erase(0, p + 2);
      std::string literal;
      if (const auto a = what.find('\''), b = what.rfind('\''); a != std::string::npos && b > a)
        literal = what.substr(a + 1, b - a - 1);
      SpecParseResult r;
      const std::string key = literal.empty() ? "" : jsonKeyBefore(text, literal);
      r.errors.push_back({key.empty() ? sourceName(options, "<json>") : key,
                          oneLine("JSON " + what + ": outside the range of a number (±1.8e308)")});
      return r;
    }
    if (!duplicates.mergeScene(doc) && duplicates.disagreement) {
      SpecParseResult r;
      r.errors.push_back(
          {"scene", "'" + *duplicates.scene_name + "' beside a \"scene\" table whose kind is " +
                        duplicates.scene_table->at("kind").dump() + ": give the scene once"});
      return r;
    }
    if (!duplicates.found.empty()) {
      SpecParseResult r;
      for (const std::string& key : duplicates.found)
        r.errors.push_back({key.empty() ? sourceName(options, "<json>") : key,
                            "given twice in one JSON object (a JSON reader keeps only the last "
                            "one): give it once"});
      return r;
    }
    return parseSpecJson(doc, base, options);
  }

  SpecParseResult result;
  const std::string source = sourceName(options, "<toml>");
  toml::table doc;
  try {
    doc = toml::parse(liftSceneTable(text), source);
  } catch (const toml::parse_error& e) {
    std::ostringstream msg;
    msg << "TOML parse error at line " << e.source().begin.line << ", column "
        << e.source().begin.column;
    if (const std::string key = tomlKeyAt(text, e.source().begin.line); !key.empty())
      msg << " (the value of " << key << ")";
    msg << ": " << e.description();
    result.errors.push_back({source, oneLine(msg.str())});
    return result;
  }
  SceneSpec spec = base;
  Walker w(spec, result, options.record);
  walkToml(doc, "", w);
  return finish(std::move(spec), std::move(result), options);
}

namespace {

// A spec is at most this long (foam's and foamd's limit too): reading stops one byte past it, so
// that /dev/zero or an endless pipe is refused at once instead of filling the memory.
constexpr std::size_t kMaxSpecFileBytes = 1 << 20;

bool readCapped(std::istream& in, std::string& text) {
  text.resize(kMaxSpecFileBytes + 1);
  in.read(text.data(), static_cast<std::streamsize>(text.size()));
  text.resize(static_cast<std::size_t>(in.gcount()));
  return text.size() <= kMaxSpecFileBytes;
}

}  // namespace

SpecParseResult parseSpecFile(const std::filesystem::path& path, const SceneSpec& base,
                              const SpecParseOptions& options) {
  SpecParseOptions opts = options;
  const bool from_stdin = path == "-";
  if (opts.source.empty()) opts.source = from_stdin ? "<stdin>" : path.string();
  std::string text;
  auto tooLong = [&] {
    std::string what = "standard input";
    if (!from_stdin) what = std::string(1, '\'').append(path.string()).append(1, '\'');
    SpecParseResult r;
    r.errors.push_back(
        {opts.source, what.append(" holds more than 1 MiB: a spec is at most 1 MiB")});
    return r;
  };
  if (from_stdin) {
    if (!readCapped(std::cin, text)) return tooLong();
  } else {
    std::error_code ec;
    if (std::filesystem::is_directory(path, ec)) {
      SpecParseResult r;
      r.errors.push_back({opts.source, "cannot read: is a directory"});
      return r;
    }
    std::ifstream in(path, std::ios::binary);
    if (!in) {
      SpecParseResult r;
      r.errors.push_back({opts.source, std::string("cannot read: ") + std::strerror(errno)});
      return r;
    }
    if (!readCapped(in, text)) return tooLong();
  }
  std::string ext = from_stdin ? "" : path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  const SpecFormat format = ext == ".toml"   ? SpecFormat::Toml
                            : ext == ".json" ? SpecFormat::Json
                                             : SpecFormat::Auto;
  return parseSpecText(text, format, base, opts);
}

std::optional<SpecError> applySetting(SceneSpec& spec, std::string_view kv) {
  const auto eq = kv.find('=');
  const std::string_view key = trim(eq == std::string_view::npos ? kv : kv.substr(0, eq));
  if (eq == std::string_view::npos || key.empty())
    return SpecError{std::string(kv), "expected key=value, e.g. numerics.dt_s=0.05"};
  const SpecField* f =
      findField(isPrepareKey(key) ? key.substr(kPrepare.size() + 1) : key);  // its value's type
  return setField(spec, key, settingValue(f, kv.substr(eq + 1)));
}

SpecParseResult applySettings(const SceneSpec& base, const std::vector<std::string>& settings) {
  SpecParseResult result;
  SceneSpec spec = base;
  for (const std::string& s : settings) {
    if (auto e = applySetting(spec, s)) {
      result.errors.push_back(*e);
      continue;
    }
    const std::string_view key = trim(std::string_view(s).substr(0, s.find('=')));
    if (isSceneKey(key)) result.scene_given = true;
    result.keys.emplace_back(key);
  }
  if (result.errors.empty()) result.spec = std::move(spec);
  return result;
}

std::vector<SpecError> checkSceneKeys(const SceneSpec& spec, const std::vector<std::string>& keys) {
  const SceneKind scene = spec.scene;
  // A resolved spec (spec.json, what foamd hands a Slurm task) lists every key with the value
  // resolve gives it; only a value other than that is a key someone set for this run. The
  // [scene] and numerics keys are compared with what resolve gives for these cells and preset,
  // the cells' own keys with what it gives for default cells.
  SceneSpec plain;
  plain.scene = scene;
  applyPreset(plain.numerics, spec.numerics.preset);
  const SceneSpec default_cells = resolve(plain);
  plain.cells = spec.cells;
  const SceneSpec defaults = resolve(plain);
  // Which scenes read each key is the key table's (SpecField::scenes). A reduced key is judged
  // by the absolute one it sets (resolve clears it).
  auto judgedBy = [](std::string_view key) -> std::string_view {
    if (key == "cells.pa_reduced") return "cells.p_a";
    if (key == "cells.l_eta_reduced") return "cells.xi";
    return key;
  };
  std::vector<SpecError> errors;
  std::vector<std::string_view> seen;
  for (const std::string& key : keys) {
    const SpecField* f = findField(key);
    if (!f || std::find(seen.begin(), seen.end(), f->key) != seen.end()) continue;
    if (f->readBy(scene)) {
      const std::string why = unreadCondition(spec, f->key);
      if (why.empty()) continue;
      // Compared with the value it would have unset here: an optional key's derived default
      // (numerics.dt_min_s: this spec's Δt/64), another key's plain default.
      SceneSpec unset = spec;
      if (f->optional)
        (void)clearField(unset, f->key);
      else if (const auto v = getField(defaults, f->key))
        (void)setField(unset, f->key, *v);
      if (getField(spec, f->key) == getField(resolve(unset), f->key)) continue;
      seen.push_back(f->key);
      errors.push_back({key, "not used: " + why + "; remove it, or change that setting"});
      continue;
    }
    seen.push_back(f->key);
    const std::string_view field = judgedBy(f->key);
    const SceneSpec& reference = field.substr(0, 6) == "cells." ? default_cells : defaults;
    if (getField(spec, field) == getField(reference, field)) continue;
    std::string list;
    for (SceneKind k :
         {SceneKind::Cell, SceneKind::Doublet, SceneKind::Spheroid, SceneKind::Fusion})
      if (f->readBy(k)) list += (list.empty() ? "" : ", ") + std::string(toString(k));
    errors.push_back({key, "not used by the " + std::string(toString(scene)) + " scene (only by: " +
                               list + "); remove it, or run the scene it belongs to"});
  }
  return errors;
}

SpecParseResult validateAndResolve(const SceneSpec& spec) {
  SpecParseResult result;
  result.errors = validate(spec);
  if (result.errors.empty()) result.spec = resolve(spec);
  return result;
}

nlohmann::json specToJson(const SceneSpec& spec) {
  nlohmann::json j = nlohmann::json::object();
  for (const SpecField& f : specFields()) {
    const std::optional<SpecValue> v = getField(spec, f.key);
    nlohmann::json value;  // null when unset
    if (v) {
      std::visit([&](const auto& x) { value = x; }, *v);
    }
    if (f.key == "scene") {
      j["scene"]["kind"] = value;
      continue;
    }
    const auto dot = f.key.find('.');
    if (dot == std::string::npos)
      j[f.key] = value;
    else
      j[f.key.substr(0, dot)][f.key.substr(dot + 1)] = value;
  }
  // Only where there is one: a spec without [prepare] is written as before.
  for (const auto& [key, v] : spec.prepare) {
    nlohmann::json value;
    std::visit([&](const auto& x) { value = x; }, v);
    const auto dot = key.find('.');
    j["prepare"][key.substr(0, dot)][key.substr(dot + 1)] = value;
  }
  return j;
}

}  // namespace activefoam
