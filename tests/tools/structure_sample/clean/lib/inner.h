#pragma once
int inner();
