#include "JsonFile.h"

#include <fstream>
#include <sstream>

namespace seasonview {

namespace {

std::string lineColumn(const std::string& text, size_t byte) {
    size_t line = 1, col = 1;
    for (size_t i = 0; i < byte && i < text.size(); ++i) {
        if (text[i] == '\n') {
            ++line;
            col = 1;
        } else {
            ++col;
        }
    }
    return "line " + std::to_string(line) + ", column " + std::to_string(col);
}

struct TooDeep {};

} // namespace

Result<nlohmann::json> parseJson(const std::string& text, const std::string& name, const std::string& what) {
    // The parser callback sees the depth of every value as it opens: the walk stops at the first one too deep.
    const nlohmann::json::parser_callback_t depthLimit = [](int depth, nlohmann::json::parse_event_t event,
                                                            nlohmann::json&) {
        if (depth >= kMaxJsonDepth && (event == nlohmann::json::parse_event_t::object_start ||
                                       event == nlohmann::json::parse_event_t::array_start))
            throw TooDeep{};
        return true;
    };
    try {
        return nlohmann::json::parse(text, depthLimit);
    } catch (const TooDeep&) {
        return fileError(name, "JSON nested deeper than " + std::to_string(kMaxJsonDepth) + " levels (the limit)");
    } catch (const nlohmann::json::parse_error& e) {
        return fileError(name, "malformed JSON " + what + " (" + lineColumn(text, e.byte ? e.byte - 1 : 0) + ")");
    } catch (const nlohmann::json::exception& e) {
        return fileError(name, "malformed JSON " + what + " (" + firstLine(e.what()) + ")");
    }
}

Result<nlohmann::json> readJsonFile(const std::filesystem::path& file, const std::string& what) {
    const std::string name = file.string();
    std::error_code ec;
    if (!std::filesystem::exists(file, ec)) return fileError(name, "file not found");
    if (std::filesystem::is_directory(file, ec)) return fileError(name, "is a directory, not a JSON " + what);
    const auto bytes = std::filesystem::file_size(file, ec);
    if (!ec && bytes > kMaxJsonBytes)
        return fileError(name, "JSON " + what + " of " + std::to_string(bytes) + " bytes is over the limit of " +
                                   std::to_string(kMaxJsonBytes >> 20) + " MiB");
    std::ifstream f(file, std::ios::binary);
    if (!f) return fileError(name, "cannot read file");
    std::stringstream buf;
    buf << f.rdbuf();
    if (f.bad()) return fileError(name, "cannot read file");
    return parseJson(buf.str(), name, what);
}

} // namespace seasonview
