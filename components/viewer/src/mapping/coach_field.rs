//! The Nao coach game's field: its lines once, the team world model and each robot's local model,
//! in 3D and in 2D.

use super::*;

impl Mapper {
    /// The field's lines, once: `field3d/lines` (m, z = 0) and `field2d/lines` (m, y flipped).
    pub(super) fn field_lines(&mut self, out: &mut Vec<Logged>) {
        if self.field_drawn {
            return;
        }
        let Some(f) = &self.field else { return };
        self.field_drawn = true;
        let mut strips: Vec<Vec<[f32; 2]>> =
            f.lines().iter().map(|l| vec![mm2(l.a), mm2(l.b)]).collect();
        let r = f.center_circle_diameter_mm as f32 / 2000.0;
        strips.push(
            (0..=48)
                .map(|i| {
                    let a = i as f32 / 48.0 * std::f32::consts::TAU;
                    [r * a.cos(), r * a.sin()]
                })
                .collect(),
        );
        let s3: Vec<Vec<[f32; 3]>> = strips
            .iter()
            .map(|s| s.iter().map(|p| [p[0], p[1], 0.0]).collect())
            .collect();
        let s2: Vec<Vec<[f32; 2]>> = strips
            .iter()
            .map(|s| s.iter().map(|p| [p[0], -p[1]]).collect())
            .collect();
        let w = f.line_width_mm as f32 / 2000.0;
        out.push(Logged::fixed(
            "field3d/lines",
            rerun::LineStrips3D::new(s3)
                .with_colors([WHITE])
                .with_radii([w]),
        ));
        out.push(Logged::fixed(
            "field2d/lines",
            rerun::LineStrips2D::new(s2)
                .with_colors([WHITE])
                .with_radii([w]),
        ));
        let posts: Vec<[f32; 2]> = f
            .landmarks
            .iter()
            .filter(|l| l.class == "goalpost")
            .map(|l| mm2([l.x_mm, l.y_mm]))
            .collect();
        let post_r = f.goalpost_diameter_mm as f32 / 2000.0;
        out.push(Logged::fixed(
            "field3d/goalposts",
            rerun::Points3D::new(posts.iter().map(|p| [p[0], p[1], 0.0]))
                .with_radii([post_r])
                .with_colors([WHITE]),
        ));
        out.push(Logged::fixed(
            "field2d/goalposts",
            rerun::Points2D::new(posts.iter().map(|p| [p[0], -p[1]]))
                .with_radii([post_r])
                .with_colors([WHITE]),
        ));
    }

    pub(super) fn world_model(&mut self, m: &nao::NaoWorldModel, out: &mut Vec<Logged>) {
        let poses: Vec<nao::FieldPose> = m.robots.iter().map(|r| r.pose).collect();
        let labels: Vec<String> = m
            .robots
            .iter()
            .map(|r| {
                format!(
                    "#{} role {}{}",
                    r.player_number,
                    r.role,
                    if r.fallen { " FALLEN" } else { "" }
                )
            })
            .collect();
        let labels: Vec<&str> = labels.iter().map(String::as_str).collect();
        field_poses(out, "robots", &poses, &labels, BLUE);
        if m.ball_known {
            field_points(
                out,
                "ball",
                &[m.ball],
                0.05,
                ORANGE,
                &[&format!("ball ({:.1} s)", m.ball_age_s)],
            );
        } else {
            out.push(Logged::new("field2d/ball", rerun::Clear::flat()));
            out.push(Logged::new("field3d/ball", rerun::Clear::flat()));
        }
        let obstacles: Vec<nao::FieldPoint> = m.obstacles.iter().map(|o| o.center).collect();
        field_points(out, "obstacles", &obstacles, 0.15, RED, &[]);
    }

    pub(super) fn local_model(&mut self, m: &nao::NaoLocalModel, out: &mut Vec<Logged>) {
        let n = m.player_number;
        field_poses(
            out,
            &format!("local/{n}/pose"),
            &[m.pose],
            &[&format!("#{n} (own estimate)")],
            rerun::Color::from_rgb(120, 170, 255),
        );
        field_points(
            out,
            &format!("local/{n}/ball"),
            &[m.ball],
            0.04,
            YELLOW,
            &[],
        );
        field_points(
            out,
            "team_ball",
            &[m.team_ball],
            0.05,
            ORANGE,
            &["team ball"],
        );
        let seen: Vec<nao::FieldPoint> = m.obstacles.iter().map(|o| o.center).collect();
        field_points(out, &format!("local/{n}/obstacles"), &seen, 0.1, RED, &[]);
    }
}
