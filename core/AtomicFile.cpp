#include "AtomicFile.h"

#include <fstream>
#include <system_error>

#include <unistd.h>

namespace seasonview {

std::filesystem::path temporaryPathFor(const std::filesystem::path& target) {
    std::filesystem::path name = "." + target.stem().string() + ".partial-" + std::to_string(::getpid()) +
                                 target.extension().string();
    return target.parent_path() / name;
}

bool commitTemporary(const std::filesystem::path& tmp, const std::filesystem::path& target, std::string& error) {
    std::error_code ec;
    std::filesystem::rename(tmp, target, ec);
    if (ec) {
        error = "cannot rename into place: " + ec.message();
        discardTemporary(tmp);
        return false;
    }
    return true;
}

void discardTemporary(const std::filesystem::path& tmp) {
    std::error_code ec;
    std::filesystem::remove(tmp, ec);
}

bool writeTextAtomic(const std::filesystem::path& target, const std::string& text, std::string& error) {
    std::filesystem::path tmp = temporaryPathFor(target);
    {
        std::ofstream f(tmp, std::ios::binary);
        if (!f) {
            error = "cannot create file";
            return false;
        }
        f.write(text.data(), std::streamsize(text.size()));
        f.close();
        if (!f) {
            error = "write failed";
            discardTemporary(tmp);
            return false;
        }
    }
    return commitTemporary(tmp, target, error);
}

} // namespace seasonview
