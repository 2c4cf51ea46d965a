// A colour gradient kept on the device (∂L/∂colour, three values a pixel) added into each
// pixel's record of a band (`PixelGrad` or `ColourGrad`: both name their colour gradients
// `channels`): the twin of the colour part of `pixel::pixel_grads`, which the host's fold then
// leaves out. The colour channels take the gradient and the final transmittance's coefficient
// loses background · gradient. The records hold the host's fold of the other gradients, or
// zeros.

@compute @workgroup_size(256)
fn colour_grad_add(ids: Ids) {
    let i = thread_1d(ids);
    if (i >= pass_.n) {
        return;
    }
    let g = vec3<f32>(colour_grad[3u * i], colour_grad[3u * i + 1u], colour_grad[3u * i + 2u]);
    var r = pixgrad[i];
    for (var k = 0u; k < 3u; k++) {
        r.channels[k] += g[k];
    }
    r.final_t -= cam.bg_r * g.x + cam.bg_g * g.y + cam.bg_b * g.z;
    pixgrad[i] = r;
}
