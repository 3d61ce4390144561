#include "AtomicFile.h"

#include <cerrno>
#include <cstdlib>
#include <fstream>
#include <system_error>

#include <signal.h>
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
    removeStaleTemporaries(target.parent_path().empty() ? std::filesystem::path(".") : target.parent_path());
    return true;
}

void removeStaleTemporaries(const std::filesystem::path& dir) {
    std::error_code ec;
    for (std::filesystem::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
        const std::string name = it->path().filename().string();
        const auto at = name.find(".partial-");
        if (at == std::string::npos) continue;
        char* digitsEnd = nullptr;
        const long pid = std::strtol(name.c_str() + at + 9, &digitsEnd, 10);
        if (digitsEnd == name.c_str() + at + 9 || pid <= 0 || pid == long(::getpid())) continue;
        if (::kill(pid_t(pid), 0) != 0 && errno == ESRCH) {
            std::error_code ignored;
            std::filesystem::remove_all(it->path(), ignored);
        }
    }
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
