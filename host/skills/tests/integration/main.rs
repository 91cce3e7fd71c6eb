//! `ferrobot-skills`' integration tests as one binary: a module per skill, and the skills
//! under hostile values.

mod grasp;
mod hand_eye;
mod hostile_skills;
mod push;
