#pragma once
// libjpeg plumbing shared by BandReader (JPEG TIFF tiles decoded) and GeoTiffStreamWriter (encoded): an error manager
// whose error_exit longjmps back to the caller instead of exiting, and keeps the message. Internal to core.
#include <csetjmp>
#include <cstdio> // jpeglib.h needs FILE

#include <jpeglib.h>

namespace seasonview::jpeg {

/// Install with `install(cinfo)`, then `if (setjmp(error.jump)) { ... }` before libjpeg calls; nothing with a
/// destructor may be created between the setjmp and the calls that may jump.
struct ErrorManager {
    jpeg_error_mgr mgr{}; // first: libjpeg's pointer to it is one to this (standard layout)
    std::jmp_buf jump{};
    char message[JMSG_LENGTH_MAX] = {}; // libjpeg's last error or warning

    template <typename Info> void install(Info& cinfo) {
        cinfo.err = jpeg_std_error(&mgr);
        mgr.error_exit = [](j_common_ptr c) {
            auto* self = reinterpret_cast<ErrorManager*>(c->err);
            remember(c);
            std::longjmp(self->jump, 1);
        };
        mgr.output_message = remember; // warnings: kept, not printed
    }
    static void remember(j_common_ptr c) {
        (*c->err->format_message)(c, reinterpret_cast<ErrorManager*>(c->err)->message);
    }
};

} // namespace seasonview::jpeg
