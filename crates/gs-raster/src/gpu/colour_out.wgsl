// The rendered colour of each pixel of a band into a device image, the twin of
// `pixel::assemble`'s colour (accumulated colour + T_final · background): a render whose colour
// stays on the device (RenderRequest::color_on_device) writes this instead of reading back three
// planes. `acc` is the band's accumulators (plane c at c · pass_.n), `final_t` the band's
// T_final, `image` the band's pixels (three values each). pass_.mode = 1: nothing was blended
// (no intersections), and the buffers hold no render: the background alone.

@compute @workgroup_size(256)
fn colour_out(ids: Ids) {
    let i = thread_1d(ids);
    let npix = pass_.n;
    if (i >= npix) {
        return;
    }
    var bg = array<f32, 3>(cam.bg_r, cam.bg_g, cam.bg_b);
    for (var c = 0u; c < 3u; c++) {
        var v = bg[c];
        if (pass_.mode == 0u) {
            v = acc[c * npix + i] + final_t[i] * bg[c];
        }
        image[3u * i + c] = v;
    }
}
