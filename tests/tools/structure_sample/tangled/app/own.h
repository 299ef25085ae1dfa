#pragma once
int own();
