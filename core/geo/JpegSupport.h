#pragma once
// libjpeg plumbing shared by BandReader (JPEG TIFF tiles decoded) and GeoTiffStreamWriter (encoded): an error manager
// whose error_exit longjmps back to the caller instead of exiting, and keeps the message. Warnings that mean lost
// pixels (a stream cut short, corrupt entropy-coded data: libjpeg then pads with grey) are errors too; harmless ones
// (extraneous bytes before a marker, an unusual Adobe transform) are tolerated, as libtiff and GDAL do. Internal to
// core.
#include <csetjmp>
#include <cstdio> // jpeglib.h needs FILE

#include <jpeglib.h>
#include <jerror.h> // the message codes

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
        mgr.emit_message = [](j_common_ptr c, int level) {
            if (level >= 0) return; // trace messages
            auto* self = reinterpret_cast<ErrorManager*>(c->err);
            remember(c);
            ++c->err->num_warnings;
            if (losesData(c->err->msg_code)) std::longjmp(self->jump, 1);
        };
    }
    /// libjpeg warnings after which the decoded pixels are not the stored ones.
    static bool losesData(int code) {
        return code == JWRN_JPEG_EOF || code == JWRN_HIT_MARKER || code == JWRN_MUST_RESYNC ||
               code == JWRN_HUFF_BAD_CODE || code == JWRN_ARITH_BAD_CODE || code == JWRN_BOGUS_PROGRESSION ||
               code == JWRN_NOT_SEQUENTIAL;
    }
    static void remember(j_common_ptr c) {
        (*c->err->format_message)(c, reinterpret_cast<ErrorManager*>(c->err)->message);
    }
};

} // namespace seasonview::jpeg
