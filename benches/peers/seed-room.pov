// The seed room (scenes/seed-room.json) for POV-Ray 3.7, for the speed
// comparison of issue 4. Render with: +W1920 +H1080 -A +WT2 (run.sh).
//
// Matched: camera (position, look_at, vertical fov 36°, 16:9) with the image's
// right = forward × up = world -x (POV-Ray is left-handed: `right -x*…`
// gives penumbra's right-handed picture); walls, two boxes rotated about y,
// mirror sphere; a 2×2 area light at the same place sampled 8×8 (POV-Ray's
// 8×8 lights span the rectangle edge to edge, penumbra's grid takes cell
// centres); Blinn-Phong specular (POV-Ray `specular` is (N·H)^(1/roughness));
// reflection added on top of the local colour as in penumbra; trace level 4
// (penumbra depth 4), no anti-aliasing, no radiosity, no jitter, no adaptive
// sampling.
// Not matched: POV-Ray's light has one colour for diffuse and specular
// (0.9; the specular amounts are divided by 0.9 to compensate), and it also
// lights the ceiling, which penumbra's one-sided light does not.

#version 3.7;

global_settings {
  assumed_gamma 1.0
  ambient_light rgb 1
  max_trace_level 4
  adc_bailout 1/1024
}

background { rgb 0 }

camera {
  perspective
  location <0, 4, -14>
  look_at <0, 3.5, 0>
  sky y
  right -x * image_width / image_height
  up y
  // POV-Ray's angle is horizontal: 2·atan(tan(36°/2) · 16/9).
  angle 2 * degrees(atan(tan(radians(18)) * image_width / image_height))
}

// Light: penumbra's corner (-1, 7.99, -1), edges (2,0,0) and (0,0,2);
// POV-Ray places an area light by its centre. area_illumination shades with
// every light point, like penumbra's default `sampled` model.
light_source {
  <0, 7.99, 0>
  color rgb 0.9
  area_light <2, 0, 0>, <0, 0, 2>, 8, 8
  area_illumination on
  looks_like {
    box { <-1, -0.0001, -1>, <1, 0.0001, 1>
      pigment { rgb 0.9 } finish { ambient 1 diffuse 0 specular 0 } }
  }
}

// Materials: pigment = penumbra's diffuse colour; ambient = light ambient
// 0.1 × (material ambient / diffuse); specular = material specular / 0.9;
// roughness = 1 / shininess.
#declare White  = texture { pigment { rgb <0.8, 0.8, 0.8> }  finish { ambient 0.1 diffuse 1 specular 0.3333 roughness 1/20 } }
#declare Red    = texture { pigment { rgb <0.8, 0.2, 0.2> }  finish { ambient 0.1 diffuse 1 specular 0.3333 roughness 1/20 } }
#declare Green  = texture { pigment { rgb <0.2, 0.8, 0.2> }  finish { ambient 0.1 diffuse 1 specular 0.3333 roughness 1/20 } }
#declare Steel  = texture { pigment { rgb <0.6, 0.6, 0.75> } finish { ambient 0.1167 diffuse 1 specular 0.6667 roughness 1/100 reflection 0.3 } }
#declare Sand   = texture { pigment { rgb <0.9, 0.8, 0.5> }  finish { ambient 0.1 diffuse 1 specular 0.3333 roughness 1/20 } }
#declare Mirror = texture { pigment { rgb <0.2, 0.2, 0.2> }  finish { ambient 0.025 diffuse 1 specular 1 roughness 1/500 reflection 0.8 } }

plane { <0, 1, 0>, 0   texture { White } }   // floor y = 0
plane { <0, -1, 0>, -8 texture { White } }   // ceiling y = 8
plane { <-1, 0, 0>, -5 texture { Red } }     // x = 5
plane { <1, 0, 0>, -5  texture { Green } }   // x = -5
plane { <0, 0, -1>, -5 texture { White } }   // back wall z = 5

// Boxes rotate about their own centre; both centres lie on the y axis
// before translation, so rotating about the world y axis is the same.
box { <-1, 0, -1>, <1, 5, 1>   rotate y * 20  translate <-2, 0, 1>    texture { Steel } }
box { <-1, 0, -1>, <1, 2.5, 1> rotate y * -15 translate <2, 0, -1.5>  texture { Sand } }

sphere { <2, 3.5, -1.5>, 1 texture { Mirror } }
